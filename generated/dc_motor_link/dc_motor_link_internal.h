/* DO NOT EDIT: dc_motor_link module, generated from template internal.h.j2 by dfeif-codegen
 * 0.1.0; regenerate with `codegen build dc_motor_link`. */
/* Internal to the dc_motor_link library, not part of its API: the kernels
 * (dc_motor_link_kernels.h) and small checks shared by the node, the master and the
 * controller. */
#ifndef DC_MOTOR_LINK_INTERNAL_H
#define DC_MOTOR_LINK_INTERNAL_H

#include <stddef.h>
#include "dc_motor_link.h"
#include "dc_motor_link_kernels.h"

/* The real type, under a short name for the library sources. */
typedef dc_motor_link_real real;

/* Compile-time checks (C99: a negative array size fails the build). */
typedef char dc_motor_link_check_nmax_low[(DC_MOTOR_LINK_NMAX >= 1) ? 1 : -1];
typedef char dc_motor_link_check_nmax_high[(DC_MOTOR_LINK_NMAX < 65535) ? 1 : -1];
typedef char dc_motor_link_check_nodes[(DC_MOTOR_LINK_NNODES >= 1) ? 1 : -1];
typedef char dc_motor_link_check_real[(sizeof(dc_motor_link_real) == 8) ? 1 : -1];

/* Centring (see the node struct in dc_motor_link.h): flat outputs are stored relative to a
 * centre that moves in exact steps of 1/8, so that single precision resolves them to their own
 * size. */
#define DC_MOTOR_LINK_CENTRE_STEP ((real)0.125)
/* zeta index of each flat output */
static const uint8_t dc_motor_link_heads[DC_MOTOR_LINK_NY] = {0};

/* The whole steps of 1/8 nearest to a stored flat output (0 when it is within 1/16, or so large
 * that centring no longer matters and (long) could overflow). Subtracting it is exact. */
static inline real dc_motor_link_centre_shift(real value)
{
    real d = value / DC_MOTOR_LINK_CENTRE_STEP;
    real half;
    real whole;
    if (!(d < (real)1048576 && d > (real)-1048576)) {
        return 0;
    }
    half = (d < (real)0) ? (real)-0.5 : (real)0.5;
    whole = d + half;
    return DC_MOTOR_LINK_CENTRE_STEP * (real)(long)whole;
}

/* x stored relative to centre `from`, rewritten relative to centre `to` (NULL: absolute). */
static inline void dc_motor_link_move_origin(const real* x, const real* from, const real* to,
                                             real* out)
{
    int i;
    for (i = 0; i < DC_MOTOR_LINK_NX; i++) {
        out[i] = x[i];
    }
    for (i = 0; i < DC_MOTOR_LINK_NY; i++) {
        out[dc_motor_link_heads[i]] += to ? from[i] - to[i] : from[i];
    }
}

/* 1 if all n values are finite (x - x is 0 for finite x, NaN otherwise; no math.h macros). */
static inline int dc_motor_link_finite(const real* a, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        real d = a[i] - a[i];
        if (!(d == d)) {
            return 0;
        }
    }
    return 1;
}

/* 1 if all n pivots are strictly positive (and not NaN). */
static inline int dc_motor_link_positive(const real* piv, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        if (!(piv[i] > (real)0)) {
            return 0;
        }
    }
    return 1;
}

/* 1 if the n x n matrix is symmetric and positive definite (LDL' pivots, no square roots). */
static inline int dc_motor_link_spd_in(const real* A, int n, real* L, real* d)
{
    int i, j, k;
    for (j = 0; j < n; j++) {
        for (i = 0; i < j; i++) {
            if (A[i * n + j] < A[j * n + i] || A[i * n + j] > A[j * n + i]) {
                return 0;
            }
        }
        d[j] = A[j * n + j];
        for (k = 0; k < j; k++) {
            d[j] -= L[j * n + k] * L[j * n + k] * d[k];
        }
        if (!(d[j] > (real)0)) {
            return 0;
        }
        for (i = j + 1; i < n; i++) {
            real s = A[i * n + j];
            for (k = 0; k < j; k++) {
                s -= L[i * n + k] * L[j * n + k] * d[k];
            }
            L[i * n + j] = s / d[j];
        }
    }
    return 1;
}

static inline int dc_motor_link_spd(const real* A, int n)
{
    real L[DC_MOTOR_LINK_NYY];
    real d[DC_MOTOR_LINK_NY];
    if (n > DC_MOTOR_LINK_NY) {
        return 0;
    }
    return dc_motor_link_spd_in(A, n, L, d);
}

/* 1 if the NX x NX matrix A (a P0 at init) is symmetric positive definite (defined in node.c). */
int dc_motor_link_cov_ok(const real* A);

#endif /* DC_MOTOR_LINK_INTERNAL_H */
