# DO NOT EDIT: pvtol module, generated from template model.mk.j2 by dfeif-codegen 0.1.0;
# regenerate with `codegen build pvtol`.
#
# Makefile fragment for the pvtol library:
#     include path/to/pvtol.mk
# then compile $(PVTOL_SRCS) with $(PVTOL_CFLAGS)
# into your build's own folder (below).
# Set PVTOL_DIR (sources) or PVTOL_INC (header folder) before including
# to override where they are found.
ifndef PVTOL_DIR
PVTOL_DIR := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
endif
PVTOL_INC ?= $(PVTOL_DIR)
PVTOL_SRCS := \
	$(PVTOL_DIR)/pvtol_node.c \
	$(PVTOL_DIR)/pvtol_master.c \
	$(PVTOL_DIR)/pvtol_control.c \
	$(PVTOL_DIR)/pvtol_wire.c \
	$(PVTOL_DIR)/pvtol_kernels_filter.c \
	$(PVTOL_DIR)/pvtol_kernels_fusion.c \
	$(PVTOL_DIR)/pvtol_kernels_control.c
PVTOL_CFLAGS := -I$(PVTOL_INC)
# PVTOL_LIB_CFLAGS: the flags the published code sizes were measured with
# (BENCHMARKS.md), for the library's objects (with GCC or Clang; link with
# -Wl,--gc-sections). Put the objects in a folder of your build (OBJDIR), not beside the
# sources: codegen build refuses to replace this folder while it holds files it did not
# write. Uncommented, with OBJDIR set:
#     PVTOL_OBJS := \
#         $(patsubst $(PVTOL_DIR)/%.c,$(OBJDIR)/%.o,$(PVTOL_SRCS))
#     $(PVTOL_OBJS): $(OBJDIR)/%.o: $(PVTOL_DIR)/%.c ; mkdir -p $(@D) && \
#         $(CC) $(CFLAGS) $(PVTOL_CFLAGS) $(PVTOL_LIB_CFLAGS) -c $< -o $@
# then link $(PVTOL_OBJS) with $(PVTOL_LDLIBS).
PVTOL_LIB_CFLAGS := -ffunction-sections -fdata-sections -fno-math-errno
PVTOL_LDLIBS := -lm
