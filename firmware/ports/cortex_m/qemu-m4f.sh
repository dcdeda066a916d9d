#!/usr/bin/env bash
# Run a Cortex-M4F test image (startup.c + semihost.c) under QEMU's MPS2 AN386 model with semihosting:
#
#   firmware/ports/cortex_m/qemu-m4f.sh IMAGE.elf [ARG...]
#
# The image gets ARG... as argv[1..] (SYS_GET_CMDLINE; arguments must not contain spaces), reads and
# writes host files through newlib + semihosting (paths relative to the current directory), and
# its exit status (SYS_EXIT_EXTENDED) is this script's. Guest stdout/stderr are QEMU's.
# QEMU_M4F_TIMEOUT (seconds, default 0 = none) stops a run that hangs (exit status 124).
set -euo pipefail
if [ $# -lt 1 ]; then
  echo "usage: $0 IMAGE.elf [ARG...]" >&2
  exit 125
fi
image=$1
shift
for a in "$@"; do
  case "$a" in
    "" | *" "*) echo "qemu-m4f: arguments may not be empty or contain spaces: '$a'" >&2; exit 125 ;;
  esac
done
cmd=(qemu-system-arm -M mps2-an386 -cpu cortex-m4 -nographic -monitor none -serial null
     -semihosting-config enable=on,target=native -kernel "$image" -append "$*")
if [ "${QEMU_M4F_TIMEOUT:-0}" != 0 ]; then
  exec timeout "$QEMU_M4F_TIMEOUT" "${cmd[@]}" </dev/null
fi
exec "${cmd[@]}" </dev/null
