/* DO NOT EDIT: pvtol module, generated from template internal.h.j2 by dfeif-codegen 0.1.0;
 * regenerate with `codegen build pvtol`. */
/* Internal to the pvtol library, not part of its API: the kernels
 * (pvtol_kernels.h) and small checks shared by the node, the master and the
 * controller. */
#ifndef PVTOL_INTERNAL_H
#define PVTOL_INTERNAL_H

#include <stddef.h>
#include "pvtol.h"
#include "pvtol_kernels.h"

/* The real type, under a short name for the library sources. */
typedef pvtol_real real;

/* Compile-time checks: the window and node count are in range, and the public header was
 * generated with the same build options as this library. */
#if (PVTOL_NMAX < 1) || (PVTOL_NMAX >= 65535)
#error "PVTOL_NMAX must be in 1..65534"
#endif
#if PVTOL_NNODES < 1
#error "PVTOL_NNODES must be at least 1"
#endif
#if PVTOL_PRECISION_FLOAT != 0
#error "pvtol.h comes from another build (PVTOL_PRECISION_FLOAT)"
#endif
#if PVTOL_OOSM_RETRODICT != 0
#error "pvtol.h comes from another build (PVTOL_OOSM_RETRODICT)"
#endif
#if PVTOL_FUSION_PAPER != 0
#error "pvtol.h comes from another build (PVTOL_FUSION_PAPER)"
#endif
#if PVTOL_FUSION_DIFFERENCE != 1
#error "pvtol.h comes from another build (PVTOL_FUSION_DIFFERENCE)"
#endif
#if PVTOL_FUSION_CI != 0
#error "pvtol.h comes from another build (PVTOL_FUSION_CI)"
#endif
#if PVTOL_PREDICTS_WITH_U != 1
#error "pvtol.h comes from another build (PVTOL_PREDICTS_WITH_U)"
#endif
#if PVTOL_SCHEDULED != 0
#error "pvtol.h comes from another build (PVTOL_SCHEDULED)"
#endif
#if PVTOL_CI_ITERATIONS != 8
#error "pvtol.h comes from another build (PVTOL_CI_ITERATIONS)"
#endif

/* Centring (see the node struct in pvtol.h): each flat output is stored relative to a
 * centre that moves in exact steps of its own, so that single precision resolves it to its own
 * size. The steps are powers of two, at most 1/8 and at most 1/16 of the range the model
 * declares for the output. The steps: 1/8, 1/8. */
/* zeta index of each flat output (defined in control.c) */
extern const uint8_t pvtol_heads[PVTOL_NY];

/* The whole steps nearest to a stored flat output (0 when it is within half a step, or beyond
 * 2^20 steps, left uncentred so that (long) cannot overflow). Subtracting it is exact; so is
 * the product by per = 1 / step, a power of two. */
static inline real pvtol_centre_shift(real value, real step, real per)
{
    real d = value * per;
    real shift = (real)0;
    if ((d < (real)1048576) && (d > (real)-1048576)) {
        real half = (d < (real)0) ? (real)-0.5 : (real)0.5;
        real whole = d + half;
        shift = step * (real)(long)whole;
    }
    return shift;
}

/* x stored relative to centre `from`, rewritten relative to centre `to` (NULL: absolute). */
static inline void pvtol_move_origin(const real* x, const real* from, const real* to, real* out)
{
    int i;
    for (i = 0; i < PVTOL_NX; i++) {
        out[i] = x[i];
    }
    for (i = 0; i < PVTOL_NY; i++) {
        out[pvtol_heads[i]] += (to != NULL) ? (from[i] - to[i]) : from[i];
    }
}

/* 1 if all n values are finite (x - x is 0 for finite x, NaN otherwise; no math.h macros). */
static inline int pvtol_finite(const real* a, size_t n)
{
    size_t i;
    int ok = 1;
    for (i = 0; (i < n) && (ok != 0); i++) {
        real d = a[i] - a[i];
        if (!(d == d)) {
            ok = 0;
        }
    }
    return ok;
}

/* 1 if all n pivots are strictly positive (and not NaN). */
static inline int pvtol_positive(const real* piv, size_t n)
{
    size_t i;
    int ok = 1;
    for (i = 0; (i < n) && (ok != 0); i++) {
        if (!(piv[i] > (real)0)) {
            ok = 0;
        }
    }
    return ok;
}

/* 1 if the n x n matrix is symmetric and positive definite (LDL' pivots, no square roots). */
static inline int pvtol_spd_in(const real* A, int n, real* L, real* d)
{
    int i;
    int j;
    int k;
    int ok = 1;
    for (j = 0; (j < n) && (ok != 0); j++) {
        for (i = 0; i < j; i++) {
            if ((A[(i * n) + j] < A[(j * n) + i]) || (A[(i * n) + j] > A[(j * n) + i])) {
                ok = 0;
            }
        }
        d[j] = A[(j * n) + j];
        for (k = 0; k < j; k++) {
            d[j] -= L[(j * n) + k] * L[(j * n) + k] * d[k];
        }
        if (!(d[j] > (real)0)) {
            ok = 0;
        }
        for (i = j + 1; (i < n) && (ok != 0); i++) {
            real s = A[(i * n) + j];
            for (k = 0; k < j; k++) {
                s -= L[(i * n) + k] * L[(j * n) + k] * d[k];
            }
            L[(i * n) + j] = s / d[j];
        }
    }
    return ok;
}

static inline int pvtol_spd(const real* A, int n)
{
    real L[PVTOL_NYY];
    real d[PVTOL_NY];
    int ok = 0;
    if (n <= PVTOL_NY) {
        ok = pvtol_spd_in(A, n, L, d);
    }
    return ok;
}

/* 1 if the NX x NX matrix A (a P0 at init) is symmetric positive definite (defined in node.c). */
int pvtol_cov_ok(const real* A);
/* 1 if the model is defined at the absolute state x (a prior at init): F-bar and G-bar finite
 * there, which every held prediction out of x evaluates whatever the input (defined in node.c). */
int pvtol_in_domain(const real* x);
/* OK, or why the master cannot take a packet's covariances (ERR_WIRE_COVARIANCE, _GAIN). */
int pvtol_packet_check(const pvtol_packet* pk);
/* master_fuse, writing the master only if commit (0: would it fuse?). */
int pvtol_master_fuse_try(pvtol_master* master, const pvtol_packet packets[PVTOL_NNODES],
                          const uint8_t present[PVTOL_NNODES], int commit);

#endif /* PVTOL_INTERNAL_H */
