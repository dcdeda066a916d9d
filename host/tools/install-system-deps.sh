#!/usr/bin/env bash
# Install the system tools the test suite needs (Debian). Runs apt-get only as root and only for
# what is missing; prints what it could not install so the tests can say why they skip.
set -u
want=()
command -v cc >/dev/null 2>&1 || want+=(gcc)
command -v clang >/dev/null 2>&1 || want+=(clang)
command -v valgrind >/dev/null 2>&1 || want+=(valgrind)
command -v objdump >/dev/null 2>&1 || want+=(binutils)
# Cross targets of tests/test_cross.py, make firmware / footprint / cycles: Cortex-M4F, M7, M33, M0+
# (newlib with semihosting, QEMU MPS2 AN386/AN500/AN505 and micro:bit), aarch64 and riscv64 (static
# glibc, qemu-user), CMake. The peers' C++ (VQF) in make cycles / footprint / bench: g++ and the
# Arm C++ library.
command -v arm-none-eabi-gcc >/dev/null 2>&1 || want+=(gcc-arm-none-eabi)
[ -f /usr/lib/arm-none-eabi/lib/rdimon.specs ] || want+=(libnewlib-arm-none-eabi)
[ -d /usr/lib/arm-none-eabi/include/c++ ] || want+=(libstdc++-arm-none-eabi-newlib)
command -v g++ >/dev/null 2>&1 || want+=(g++)
command -v qemu-system-arm >/dev/null 2>&1 || want+=(qemu-system-arm)
{ command -v qemu-aarch64-static && command -v qemu-riscv64-static; } >/dev/null 2>&1 || want+=(qemu-user-static)
command -v aarch64-linux-gnu-gcc >/dev/null 2>&1 || want+=(gcc-aarch64-linux-gnu)
[ -f /usr/aarch64-linux-gnu/lib/libc.a ] || want+=(libc6-dev-arm64-cross)
command -v riscv64-linux-gnu-gcc >/dev/null 2>&1 || want+=(gcc-riscv64-linux-gnu)
[ -f /usr/riscv64-linux-gnu/lib/libc.a ] || want+=(libc6-dev-riscv64-cross)
command -v cmake >/dev/null 2>&1 || want+=(cmake)
# Real SocketCAN for tests/test_vcan_uml.py: user-mode Linux with vcan, candump, insmod.
command -v linux.uml >/dev/null 2>&1 || want+=(user-mode-linux)
command -v candump >/dev/null 2>&1 || want+=(can-utils)
command -v insmod >/dev/null 2>&1 || want+=(kmod)
# Robustness (tests/test_sanitize.py, tests/test_fuzz.py; libFuzzer and the sanitizer runtimes come
# with clang): static analysers, and the i386 C library and libgcc for the -m32 build (not
# gcc-multilib: on Debian it conflicts with the aarch64/riscv64 cross compilers above).
command -v cppcheck >/dev/null 2>&1 || want+=(cppcheck)
command -v clang-tidy >/dev/null 2>&1 || want+=(clang-tidy)
[ -f /usr/include/x86_64-linux-gnu/gnu/stubs-32.h ] || want+=(libc6-dev-i386)
# attica view's browser test (tests/test_view_browser.py): Debian's chromium, headless, driven through the
# DevTools protocol (no browser download).
command -v chromium >/dev/null 2>&1 || want+=(chromium)
ls /usr/lib/gcc/x86_64-linux-gnu/*/32/libgcc.a >/dev/null 2>&1 || want+=(lib32gcc-12-dev)
for extra in "$@"; do
  case "$extra" in
    *:*) pkg=${extra%%:*}; cmd=${extra#*:} ;;
    *) pkg=$extra; cmd=$extra ;;
  esac
  command -v "$cmd" >/dev/null 2>&1 || want+=("$pkg")
done
[ ${#want[@]} -eq 0 ] && exit 0
if [ "$(id -u)" != 0 ]; then
  echo "install-system-deps: not root; missing (tests that need them will say so): ${want[*]}"
  exit 0
fi
echo "install-system-deps: apt-get install ${want[*]}"
export DEBIAN_FRONTEND=noninteractive
if ! apt-get install -y -qq "${want[@]}" >/dev/null 2>&1; then
  apt-get update -qq >/dev/null 2>&1
  apt-get install -y -qq "${want[@]}" >/dev/null 2>&1 || echo "install-system-deps: could not install: ${want[*]}"
fi
exit 0
