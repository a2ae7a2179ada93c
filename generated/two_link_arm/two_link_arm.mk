# DO NOT EDIT: two_link_arm module, generated from template model.mk.j2 by dfeif-codegen 0.1.0;
# regenerate with `codegen build two_link_arm`.
#
# Makefile fragment for the two_link_arm library:
#     include path/to/two_link_arm.mk
# then add $(TWO_LINK_ARM_SRCS) to your sources and $(TWO_LINK_ARM_CFLAGS) to CFLAGS.
# Set TWO_LINK_ARM_DIR (sources) or TWO_LINK_ARM_INC (header folder) before including
# to override where they are found.
ifndef TWO_LINK_ARM_DIR
TWO_LINK_ARM_DIR := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
endif
TWO_LINK_ARM_INC ?= $(TWO_LINK_ARM_DIR)
TWO_LINK_ARM_SRCS := \
	$(TWO_LINK_ARM_DIR)/two_link_arm_node.c \
	$(TWO_LINK_ARM_DIR)/two_link_arm_master.c \
	$(TWO_LINK_ARM_DIR)/two_link_arm_control.c \
	$(TWO_LINK_ARM_DIR)/two_link_arm_wire.c \
	$(TWO_LINK_ARM_DIR)/two_link_arm_kernels_filter.c \
	$(TWO_LINK_ARM_DIR)/two_link_arm_kernels_fusion.c \
	$(TWO_LINK_ARM_DIR)/two_link_arm_kernels_control.c
TWO_LINK_ARM_CFLAGS := -I$(TWO_LINK_ARM_INC)
# The flags the published code sizes were measured with (BENCHMARKS.md), for the library's
# objects (with GCC or Clang; link with -Wl,--gc-sections), e.g.
#     $(patsubst %.c,%.o,$(TWO_LINK_ARM_SRCS)): CFLAGS += $(TWO_LINK_ARM_LIB_CFLAGS)
TWO_LINK_ARM_LIB_CFLAGS := -ffunction-sections -fdata-sections -fno-math-errno
TWO_LINK_ARM_LDLIBS := -lm
