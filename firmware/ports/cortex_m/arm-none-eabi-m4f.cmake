# CMake toolchain file: Cortex-M4F with the GNU Arm Embedded toolchain (arm-none-eabi-gcc). From the
# repository root (docs/integration.md; tests/test_cross.py runs this line as written):
#   cmake -S firmware -B build/m4f -DCMAKE_TOOLCHAIN_FILE="$PWD/firmware/ports/cortex_m/arm-none-eabi-m4f.cmake"
# Always an absolute path: cmake looks for a relative toolchain file in the build directory. From an
# installed attica:
#   -DCMAKE_TOOLCHAIN_FILE="$(attica paths --firmware)/ports/cortex_m/arm-none-eabi-m4f.cmake"
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_AR arm-none-eabi-ar)
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
set(CMAKE_C_FLAGS_INIT "-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard -ffunction-sections -fdata-sections")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
