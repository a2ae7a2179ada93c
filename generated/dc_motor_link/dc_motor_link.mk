# DO NOT EDIT: dc_motor_link module, generated from template model.mk.j2 by dfeif-codegen 0.1.0;
# regenerate with `codegen build dc_motor_link`.
#
# Makefile fragment for the dc_motor_link library:
#     include path/to/dc_motor_link.mk
# then compile $(DC_MOTOR_LINK_SRCS) with $(DC_MOTOR_LINK_CFLAGS)
# into your build's own folder (below).
# Set DC_MOTOR_LINK_DIR (sources) or DC_MOTOR_LINK_INC (header folder) before including
# to override where they are found.
ifndef DC_MOTOR_LINK_DIR
DC_MOTOR_LINK_DIR := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
endif
DC_MOTOR_LINK_INC ?= $(DC_MOTOR_LINK_DIR)
DC_MOTOR_LINK_SRCS := \
	$(DC_MOTOR_LINK_DIR)/dc_motor_link_node.c \
	$(DC_MOTOR_LINK_DIR)/dc_motor_link_master.c \
	$(DC_MOTOR_LINK_DIR)/dc_motor_link_control.c \
	$(DC_MOTOR_LINK_DIR)/dc_motor_link_wire.c \
	$(DC_MOTOR_LINK_DIR)/dc_motor_link_kernels_filter.c \
	$(DC_MOTOR_LINK_DIR)/dc_motor_link_kernels_fusion.c \
	$(DC_MOTOR_LINK_DIR)/dc_motor_link_kernels_control.c
DC_MOTOR_LINK_CFLAGS := -I$(DC_MOTOR_LINK_INC)
# DC_MOTOR_LINK_LIB_CFLAGS: the flags the published code sizes were measured with
# (BENCHMARKS.md), for the library's objects (with GCC or Clang; link with
# -Wl,--gc-sections). Put the objects in a folder of your build (OBJDIR), not beside the
# sources: codegen build refuses to replace this folder while it holds files it did not
# write. Uncommented, with OBJDIR set:
#     DC_MOTOR_LINK_OBJS := \
#         $(patsubst $(DC_MOTOR_LINK_DIR)/%.c,$(OBJDIR)/%.o,$(DC_MOTOR_LINK_SRCS))
#     $(DC_MOTOR_LINK_OBJS): $(OBJDIR)/%.o: $(DC_MOTOR_LINK_DIR)/%.c ; mkdir -p $(@D) && \
#         $(CC) $(CFLAGS) $(DC_MOTOR_LINK_CFLAGS) $(DC_MOTOR_LINK_LIB_CFLAGS) -c $< -o $@
# then link $(DC_MOTOR_LINK_OBJS) with $(DC_MOTOR_LINK_LDLIBS).
DC_MOTOR_LINK_LIB_CFLAGS := -ffunction-sections -fdata-sections -fno-math-errno
DC_MOTOR_LINK_LDLIBS := -lm
