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

$(ATTICA_BUILD)/%.o: $(ATTICA_DIR)/src/%.c $(wildcard $(ATTICA_DIR)/include/attica/*.h) $(ATTICA_PRIVATE_HDRS) $(ATTICA_DIR)/cflags.txt
	@mkdir -p $(@D)
	$(CC) $(ATTICA_ARCH) $(ATTICA_OPT) $(ATTICA_CFLAGS) $(ATTICA_WARNINGS) $(ATTICA_INCLUDES) -c $< -o $@

$(ATTICA_LIB): $(ATTICA_OBJS)
	@rm -f $@
	$(AR) rcs $@ $^

# including this file does not change your default goal
.DEFAULT_GOAL := $(_attica_default_goal)
