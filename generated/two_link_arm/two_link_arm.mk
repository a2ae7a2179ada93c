# DO NOT EDIT: two_link_arm module, generated from template model.mk.j2 by dfeif-codegen 0.1.0;
# regenerate with `codegen build two_link_arm`.
#
# Makefile fragment for the two_link_arm library:
#     include path/to/two_link_arm.mk
# then compile $(TWO_LINK_ARM_SRCS) with $(TWO_LINK_ARM_CFLAGS)
# into your build's own folder (below).
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
# TWO_LINK_ARM_LIB_CFLAGS: the flags the published code sizes were measured with
# (BENCHMARKS.md), for the library's objects (with GCC or Clang; link with
# -Wl,--gc-sections). Put the objects in a folder of your build (OBJDIR), not beside the
# sources: codegen build refuses to replace this folder while it holds files it did not
# write. Uncommented, with OBJDIR set:
#     TWO_LINK_ARM_OBJS := \
#         $(patsubst $(TWO_LINK_ARM_DIR)/%.c,$(OBJDIR)/%.o,$(TWO_LINK_ARM_SRCS))
#     $(TWO_LINK_ARM_OBJS): $(OBJDIR)/%.o: $(TWO_LINK_ARM_DIR)/%.c ; mkdir -p $(@D) && \
#         $(CC) $(CFLAGS) $(TWO_LINK_ARM_CFLAGS) $(TWO_LINK_ARM_LIB_CFLAGS) -c $< -o $@
# then link $(TWO_LINK_ARM_OBJS) with $(TWO_LINK_ARM_LDLIBS).
TWO_LINK_ARM_LIB_CFLAGS := -ffunction-sections -fdata-sections -fno-math-errno
TWO_LINK_ARM_LDLIBS := -lm
