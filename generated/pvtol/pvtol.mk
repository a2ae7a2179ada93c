# DO NOT EDIT: pvtol module, generated from template model.mk.j2 by dfeif-codegen 0.1.0;
# regenerate with `codegen build pvtol`.
#
# Makefile fragment for the pvtol library:
#     include path/to/pvtol.mk
# then add $(PVTOL_SRCS) to your sources and $(PVTOL_CFLAGS) to CFLAGS.
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
# The flags the published code sizes were measured with (BENCHMARKS.md), for the library's
# objects (with GCC or Clang; link with -Wl,--gc-sections), e.g.
#     $(patsubst %.c,%.o,$(PVTOL_SRCS)): CFLAGS += $(PVTOL_LIB_CFLAGS)
PVTOL_LIB_CFLAGS := -ffunction-sections -fdata-sections -fno-math-errno
PVTOL_LDLIBS := -lm
