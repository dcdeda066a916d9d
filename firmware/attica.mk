# attica as a Makefile fragment for your firmware build (docs/integration.md).
#
#   include path/to/attica/firmware/attica.mk
#   CFLAGS += $(ATTICA_INCLUDES)                  # your code includes "attica/att_filter.h"
#   firmware.elf: main.o $(ATTICA_LIB)           # or link $(ATTICA_OBJS)
#
# Variables it sets:
#   ATTICA_DIR       this directory
#   ATTICA_SRCS      the library sources (every src/**/*.c: math, core, filters, calib, CAN codec, node)
#   ATTICA_INCLUDES  -I flag for the public headers, and $(ATTICA_CONFIG): put it on the compile line
#                    of every file of yours that includes an attica header
#   ATTICA_CFLAGS    the numerics flags of cflags.txt line 1 (-std=c99 -ffp-contract=off -fno-fast-math
#                    -fno-math-errno ...) and -fno-lto: attica's sources must be compiled with exactly
#                    these, after any flags of yours, for results bit-identical to the reference;
#                    and -ffunction-sections -fdata-sections, so that a link with --gc-sections drops
#                    every function (and filter kind) the application does not call
#   ATTICA_WARNINGS  the warning flags of cflags.txt line 2 (-Wall ... -Werror); set
#                    ATTICA_STRICT_WARNINGS=0 to leave them out
#   ATTICA_OBJS, ATTICA_LIB  objects and static library built under ATTICA_BUILD (default build/attica)
# The Cortex-M port (ports/cortex_m; docs/integration.md):
#   ATTICA_PORT_DIR       ports/cortex_m
#   ATTICA_PORT_INCLUDES  -I flag for att_can_hal.h, att_fdcan_hal.h, att_port.h
#   ATTICA_BXCAN_SRCS, ATTICA_FDCAN_SRCS   the bxCAN and the FDCAN / M_CAN HAL of the CAN node
#   ATTICA_FPENV_SRCS     att_fpenv.c: the floating-point environment, for a start-up of your own
#   ATTICA_STARTUP_SRCS   startup.c + att_fpenv.c: attica's own start-up (needs a linker script like
#                         ports/cortex_m/mps2_an386.ld)
#   ATTICA_BXCAN_OBJS, ATTICA_FDCAN_OBJS, ATTICA_FPENV_OBJS, ATTICA_STARTUP_OBJS  the same compiled under
#                         $(ATTICA_BUILD)/ports with the library's flags; link them with $(ATTICA_LIB):
#                         firmware.elf: main.o $(ATTICA_FDCAN_OBJS) $(ATTICA_FPENV_OBJS) $(ATTICA_LIB)
# Variables it reads (set them before the include, or on the command line):
#   CC, AR           your (cross) compiler and archiver
#   ATTICA_ARCH      CPU flags, e.g. -mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard
#   ATTICA_OPT       optimisation (default -O2; -Os is fine: every level gives the same bits)
#   ATTICA_CONFIG    the build configuration (att_config.h), e.g. -DATT_WITH_EKF=0 -DATT_WITH_CALIB=0
#                    or -DATT_CONFIG_HEADER='"my_attica_config.h"' -Ipath/to/it (default: none, every
#                    kind and the stages); a change needs a clean ATTICA_BUILD (the objects do not
#                    depend on it)
_attica_default_goal := $(.DEFAULT_GOAL)
ATTICA_DIR := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
_attica_rwildcard = $(foreach d,$(wildcard $(1:=/*)),$(call _attica_rwildcard,$d,$2) $(filter $(subst *,%,$2),$d))
ATTICA_SRCS := $(sort $(call _attica_rwildcard,$(ATTICA_DIR)/src,*.c))
ATTICA_PRIVATE_HDRS := $(sort $(call _attica_rwildcard,$(ATTICA_DIR)/src,*.h))
ATTICA_CONFIG ?=
ATTICA_INCLUDES := -I$(ATTICA_DIR)/include $(ATTICA_CONFIG)
ATTICA_CFLAGS := $(shell sed -n 1p $(ATTICA_DIR)/cflags.txt) -fno-lto -ffunction-sections -fdata-sections
ATTICA_STRICT_WARNINGS ?= 1
ATTICA_WARNINGS := $(if $(filter 1,$(ATTICA_STRICT_WARNINGS)),$(shell sed -n 2p $(ATTICA_DIR)/cflags.txt))
ATTICA_OPT ?= -O2
ATTICA_ARCH ?=
ATTICA_BUILD ?= build/attica
ATTICA_OBJS := $(patsubst $(ATTICA_DIR)/src/%.c,$(ATTICA_BUILD)/%.o,$(ATTICA_SRCS))
ATTICA_LIB := $(ATTICA_BUILD)/libattica.a
ATTICA_PORT_DIR := $(ATTICA_DIR)/ports/cortex_m
ATTICA_PORT_INCLUDES := -I$(ATTICA_PORT_DIR)
ATTICA_BXCAN_SRCS := $(ATTICA_PORT_DIR)/att_can_hal.c
ATTICA_FDCAN_SRCS := $(ATTICA_PORT_DIR)/att_fdcan_hal.c
ATTICA_FPENV_SRCS := $(ATTICA_PORT_DIR)/att_fpenv.c
ATTICA_STARTUP_SRCS := $(ATTICA_PORT_DIR)/startup.c $(ATTICA_PORT_DIR)/att_fpenv.c
_attica_port_objs = $(patsubst $(ATTICA_PORT_DIR)/%.c,$(ATTICA_BUILD)/ports/%.o,$(1))
ATTICA_BXCAN_OBJS := $(call _attica_port_objs,$(ATTICA_BXCAN_SRCS))
ATTICA_FDCAN_OBJS := $(call _attica_port_objs,$(ATTICA_FDCAN_SRCS))
ATTICA_FPENV_OBJS := $(call _attica_port_objs,$(ATTICA_FPENV_SRCS))
ATTICA_STARTUP_OBJS := $(call _attica_port_objs,$(ATTICA_STARTUP_SRCS))

$(ATTICA_BUILD)/%.o: $(ATTICA_DIR)/src/%.c $(wildcard $(ATTICA_DIR)/include/attica/*.h) $(ATTICA_PRIVATE_HDRS) $(ATTICA_DIR)/cflags.txt
	@mkdir -p $(@D)
	$(CC) $(ATTICA_ARCH) $(ATTICA_OPT) $(ATTICA_CFLAGS) $(ATTICA_WARNINGS) $(ATTICA_INCLUDES) -c $< -o $@

$(ATTICA_BUILD)/ports/%.o: $(ATTICA_PORT_DIR)/%.c $(wildcard $(ATTICA_PORT_DIR)/*.h) $(wildcard $(ATTICA_DIR)/include/attica/*.h) $(ATTICA_DIR)/cflags.txt
	@mkdir -p $(@D)
	$(CC) $(ATTICA_ARCH) $(ATTICA_OPT) $(ATTICA_CFLAGS) $(ATTICA_WARNINGS) $(ATTICA_INCLUDES) $(ATTICA_PORT_INCLUDES) -c $< -o $@

$(ATTICA_LIB): $(ATTICA_OBJS)
	@rm -f $@
	$(AR) rcs $@ $^

# including this file does not change your default goal
.DEFAULT_GOAL := $(_attica_default_goal)
