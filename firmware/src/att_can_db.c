/**
 * @file att_can_db.c
 * @brief Builds the cantools-generated pack/unpack code (firmware/can/gen/att_can_db.c, generated from
 * firmware/can/attica.dbc by host/attica/can/gen.py) as part of the firmware source list.
 *
 * The generated code compiles cleanly with the strict flags of firmware/cflags.txt: it is generated
 * with --no-floating-point-numbers --use-float, so it has no double and no float-to-int conversion.
 */
#include "att_fp.h"

#include "../can/gen/att_can_db.c"
