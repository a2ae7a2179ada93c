# DO NOT EDIT: unicycle module, generated from template model.mk.j2 by dfeif-codegen 0.1.0;
# regenerate with `codegen build unicycle`.
#
# Makefile fragment for the unicycle library:
#     include path/to/unicycle.mk
# then compile $(UNICYCLE_SRCS) with $(UNICYCLE_CFLAGS)
# into your build's own folder (below).
# Set UNICYCLE_DIR (sources) or UNICYCLE_INC (header folder) before including
# to override where they are found.
ifndef UNICYCLE_DIR
UNICYCLE_DIR := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
endif
UNICYCLE_INC ?= $(UNICYCLE_DIR)
UNICYCLE_SRCS := \
	$(UNICYCLE_DIR)/unicycle_node.c \
	$(UNICYCLE_DIR)/unicycle_master.c \
	$(UNICYCLE_DIR)/unicycle_control.c \
	$(UNICYCLE_DIR)/unicycle_wire.c \
	$(UNICYCLE_DIR)/unicycle_kernels_filter.c \
	$(UNICYCLE_DIR)/unicycle_kernels_fusion.c \
	$(UNICYCLE_DIR)/unicycle_kernels_control.c
UNICYCLE_CFLAGS := -I$(UNICYCLE_INC)
# UNICYCLE_LIB_CFLAGS: the flags the published code sizes were measured with
# (BENCHMARKS.md), for the library's objects (with GCC or Clang; link with
# -Wl,--gc-sections). Put the objects in a folder of your build (OBJDIR), not beside the
# sources: codegen build refuses to replace this folder while it holds files it did not
# write. Uncommented, with OBJDIR set:
#     UNICYCLE_OBJS := \
#         $(patsubst $(UNICYCLE_DIR)/%.c,$(OBJDIR)/%.o,$(UNICYCLE_SRCS))
#     $(UNICYCLE_OBJS): $(OBJDIR)/%.o: $(UNICYCLE_DIR)/%.c ; mkdir -p $(@D) && \
#         $(CC) $(CFLAGS) $(UNICYCLE_CFLAGS) $(UNICYCLE_LIB_CFLAGS) -c $< -o $@
# then link $(UNICYCLE_OBJS) with $(UNICYCLE_LDLIBS).
UNICYCLE_LIB_CFLAGS := -ffunction-sections -fdata-sections -fno-math-errno
UNICYCLE_LDLIBS := -lm
