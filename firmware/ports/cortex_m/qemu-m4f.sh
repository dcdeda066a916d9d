#!/usr/bin/env bash
# Run a Cortex-M4F test image (startup.c + semihost.c) under QEMU's MPS2 AN386 model with semihosting:
#
#   firmware/ports/cortex_m/qemu-m4f.sh IMAGE.elf [ARG...]
#
# The same as `qemu-cortex-m.sh m4f IMAGE.elf [ARG...]` (see there for the other boards): the image
# gets ARG... as argv[1..], reads and writes host files through newlib + semihosting, and its exit
# status is this script's. QEMU_M4F_TIMEOUT (seconds, default 0 = none) stops a run that hangs.
exec "$(dirname "$0")/qemu-cortex-m.sh" m4f "$@"
