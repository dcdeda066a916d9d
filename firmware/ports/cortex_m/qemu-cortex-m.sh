#!/usr/bin/env bash
# Run a Cortex-M test image (startup.c + semihost.c) under one of QEMU's boards with semihosting:
#
#   firmware/ports/cortex_m/qemu-cortex-m.sh BOARD IMAGE.elf [ARG...]
#
# BOARD    QEMU machine and CPU           linker script    build flags (firmware/cflags.txt plus)
# m4f      mps2-an386, cortex-m4          mps2_an386.ld    -mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard
# m7       mps2-an500, cortex-m7          mps2_an500.ld    -mcpu=cortex-m7 -mfpu=fpv5-d16 -mfloat-abi=hard
# m33      mps2-an505, cortex-m33         mps2_an505.ld    -mcpu=cortex-m33 -mfpu=fpv5-sp-d16 -mfloat-abi=hard
# m0plus   microbit, cortex-m0            microbit.ld      -mcpu=cortex-m0plus -mfloat-abi=soft
#
# The image gets ARG... as argv[1..] (SYS_GET_CMDLINE; arguments must not contain spaces), reads and
# writes host files through newlib + semihosting (paths relative to the current directory), and
# its exit status (SYS_EXIT_EXTENDED) is this script's. Guest stdout/stderr are QEMU's.
# QEMU_M4F_TIMEOUT (seconds, default 0 = none) stops a run that hangs (exit status 124).
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: $0 m4f|m7|m33|m0plus IMAGE.elf [ARG...]" >&2
  exit 125
fi
case "$1" in
  m4f) machine=(-M mps2-an386 -cpu cortex-m4) ;;
  m7) machine=(-M mps2-an500 -cpu cortex-m7) ;;
  m33) machine=(-M mps2-an505 -cpu cortex-m33) ;;
  m0plus) machine=(-M microbit -cpu cortex-m0) ;;
  *) echo "qemu-cortex-m: unknown board '$1' (m4f, m7, m33, m0plus)" >&2; exit 125 ;;
esac
image=$2
shift 2
for a in "$@"; do
  case "$a" in
    "" | *" "*) echo "qemu-cortex-m: arguments may not be empty or contain spaces: '$a'" >&2; exit 125 ;;
  esac
done
cmd=(qemu-system-arm "${machine[@]}" -nographic -monitor none -serial null
     -semihosting-config enable=on,target=native -kernel "$image" -append "$*")
if [ "${QEMU_M4F_TIMEOUT:-0}" != 0 ]; then
  exec timeout "$QEMU_M4F_TIMEOUT" "${cmd[@]}" </dev/null
fi
exec "${cmd[@]}" </dev/null
