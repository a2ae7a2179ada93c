/* DO NOT EDIT: two_link_arm module, generated from template master_difference.c.j2 by
 * dfeif-codegen 0.1.0; regenerate with `codegen build two_link_arm`. */
/* The master: predicts stale packets to the current step, fuses the nodes' estimates in
 * information form (difference rule) and keeps its own prediction, following
 * docs/algorithms.md. Computes into locals; writes the master only when nothing can fail. */
#include <string.h>
#include "two_link_arm_internal.h"

#define NX TWO_LINK_ARM_NX
#define NY TWO_LINK_ARM_NY
#define NXX (TWO_LINK_ARM_NX * TWO_LINK_ARM_NX)
#define NNODES TWO_LINK_ARM_NNODES
#define NMAX TWO_LINK_ARM_NMAX

size_t two_link_arm_master_size(void)
{
    return sizeof(two_link_arm_master);
}

/* Slot of step j's input in master->v. */
static int input_slot(uint32_t step)
{
    uint32_t slot = step % (uint32_t)NMAX;
    return (int)slot;
}

static int master_step(const real* x, const real* P, const real* v, const real* q, real* x1,
                       real* P1)
{
    real w[TWO_LINK_ARM_KERN_PREDICT_SZ_W];
    (void)two_link_arm_kern_predict(x, P, v, q, x1, P1, w);
    if (!two_link_arm_finite(x1, NX) || !two_link_arm_finite(P1, NXX)) {
        return TWO_LINK_ARM_ERR_NONFINITE;
    }
    return TWO_LINK_ARM_OK;
}

/* Y = P^-1, y = Y (x - c) by Cholesky: information about the centre c (the master's prior). */
static int info(const real* x, const real* P, const real* c, real* Y, real* y)
{
    real piv[NX];
    real w[TWO_LINK_ARM_KERN_INFO_SZ_W];
    (void)two_link_arm_kern_info(x, P, c, Y, y, piv, w);
    if (!two_link_arm_positive(piv, NX)) {
        return TWO_LINK_ARM_ERR_SINGULAR;
    }
    if (!two_link_arm_finite(Y, NXX) || !two_link_arm_finite(y, NX)) {
        return TWO_LINK_ARM_ERR_NONFINITE;
    }
    return TWO_LINK_ARM_OK;
}

/* Move the centre by whole steps to within 1/16 of the estimate (as the node does). */
static void master_recentre(two_link_arm_master* master)
{
    int j;
    for (j = 0; j < NY; j++) {
        real shift = two_link_arm_centre_shift(master->x[two_link_arm_heads[j]]);
        master->centre[j] += shift;
        master->x[two_link_arm_heads[j]] -= shift;
        master->x_prior[two_link_arm_heads[j]] -= shift;
    }
}

/* Predict (x, P) from step j to step k with the stored inputs (in place, through a copy). */
static int catch_up(const two_link_arm_master* master, uint32_t j, real* x, real* P)
{
    real x1[NX], P1[NXX];
    uint32_t s;
    int rc;
    for (s = j; s < master->k; s++) {
        rc = master_step(x, P, &master->v[input_slot(s) * NY], master->q, x1, P1);
        if (rc != TWO_LINK_ARM_OK) {
            return rc;
        }
        (void)memcpy(x, x1, sizeof(x1));
        (void)memcpy(P, P1, sizeof(P1));
    }
    return TWO_LINK_ARM_OK;
}

int two_link_arm_master_init(two_link_arm_master* master, const real x0[NX], const real P0[NXX],
                             const real q[NY])
{
    int i;
    if (!master || !x0 || !P0 || !q) {
        return TWO_LINK_ARM_ERR_ARG;
    }
    if (!two_link_arm_finite(x0, NX) || !two_link_arm_finite(P0, NXX) ||
        !two_link_arm_finite(q, NY)) {
        return TWO_LINK_ARM_ERR_NONFINITE;
    }
    for (i = 0; i < NY; i++) {
        if (q[i] < (real)0) {
            return TWO_LINK_ARM_ERR_ARG;
        }
    }
    if (two_link_arm_cov_ok(P0) == 0) { /* P0 must be symmetric positive definite */
        return TWO_LINK_ARM_ERR_ARG;
    }
    (void)memset(master, 0, sizeof(*master));
    (void)memcpy(master->x, x0, sizeof(master->x));
    (void)memcpy(master->P, P0, sizeof(master->P));
    (void)memcpy(master->x_prior, x0, sizeof(master->x_prior));
    (void)memcpy(master->P_prior, P0, sizeof(master->P_prior));
    (void)memcpy(master->q, q, sizeof(master->q));
    master_recentre(master);
    return TWO_LINK_ARM_OK;
}

int two_link_arm_master_fuse(two_link_arm_master* master, const two_link_arm_packet packets[NNODES],
                             const uint8_t present[NNODES])
{
    real Yacc[NXX], yacc[NX], x[NX], P[NXX], Yi[NXX], yi[NX];
    real xp[NX], Pp[NXX], Ypi[NXX], ypi[NX];
    real piv[NX];
    real w[TWO_LINK_ARM_KERN_FUSE_FINISH_SZ_W];
    uint32_t used = 0, stale = 0, ignored = 0;
    int i, d, rc;
    if (!master || !packets || !present) {
        return TWO_LINK_ARM_ERR_ARG;
    }
    rc = info(master->x_prior, master->P_prior, master->x_prior, Yacc, yacc);
    if (rc != TWO_LINK_ARM_OK) {
        return rc;
    }
    for (i = 0; i < NNODES; i++) {
        const two_link_arm_packet* pk = &packets[i];
        if (present[i] > 1u) { /* 0 or 1 only; the master is changed only after this loop */
            return TWO_LINK_ARM_ERR_ARG;
        }
        if (!present[i]) {
            continue;
        }
        if (pk->step > master->k || master->k - pk->step > (uint32_t)NMAX) {
            ignored++;
            continue;
        }
        if (!two_link_arm_finite(pk->x, NX) || !two_link_arm_finite(pk->P, NXX) ||
            !two_link_arm_finite(pk->x_pred, NX) || !two_link_arm_finite(pk->P_pred, NXX) ||
            !two_link_arm_finite(pk->centre, NY)) {
            return TWO_LINK_ARM_ERR_NONFINITE;
        }
        /* the centres differ by whole steps */
        two_link_arm_move_origin(pk->x, pk->centre, master->centre, x);
        (void)memcpy(P, pk->P, sizeof(P));
        rc = catch_up(master, pk->step, x, P);
        if (rc == TWO_LINK_ARM_OK) {
            rc = info(x, P, master->x_prior, Yi, yi);
        }
        if (rc != TWO_LINK_ARM_OK) {
            return rc;
        }
        two_link_arm_move_origin(pk->x_pred, pk->centre, master->centre, xp);
        (void)memcpy(Pp, pk->P_pred, sizeof(Pp));
        rc = catch_up(master, pk->step, xp, Pp);
        if (rc == TWO_LINK_ARM_OK) {
            rc = info(xp, Pp, master->x_prior, Ypi, ypi);
        }
        if (rc != TWO_LINK_ARM_OK) {
            return rc;
        }
        for (d = 0; d < NXX; d++) {
            Yacc[d] += Yi[d] - Ypi[d];
        }
        for (d = 0; d < NX; d++) {
            yacc[d] += yi[d] - ypi[d];
        }
        used++;
        if (pk->step < master->k) {
            stale++;
        }
    }
    if (used == 0u) {
        (void)memcpy(x, master->x_prior, sizeof(x));
        (void)memcpy(P, master->P_prior, sizeof(P));
    } else {
        (void)two_link_arm_kern_fuse_finish(Yacc, yacc, master->x_prior, x, P, piv, w);
        if (!two_link_arm_positive(piv, NX)) {
            return TWO_LINK_ARM_ERR_SINGULAR;
        }
        if (!two_link_arm_finite(x, NX) || !two_link_arm_finite(P, NXX)) {
            return TWO_LINK_ARM_ERR_NONFINITE;
        }
    }
    (void)memcpy(master->x, x, sizeof(x));
    (void)memcpy(master->P, P, sizeof(P));
    master->health.fusions++;
    master->health.packets_used += used;
    master->health.packets_stale += stale;
    master->health.packets_ignored += ignored;
    return TWO_LINK_ARM_OK;
}

int two_link_arm_master_predict(two_link_arm_master* master, const real v[NY])
{
    real x1[NX], P1[NXX];
    int rc;
    if (!master || !v) {
        return TWO_LINK_ARM_ERR_ARG;
    }
    if (!two_link_arm_finite(v, NY)) {
        return TWO_LINK_ARM_ERR_NONFINITE;
    }
    rc = master_step(master->x, master->P, v, master->q, x1, P1);
    if (rc != TWO_LINK_ARM_OK) {
        return rc;
    }
    (void)memcpy(&master->v[input_slot(master->k) * NY], v, sizeof(real) * (size_t)NY);
    master->k++;
    (void)memcpy(master->x_prior, x1, sizeof(x1));
    (void)memcpy(master->P_prior, P1, sizeof(P1));
    (void)memcpy(master->x, x1, sizeof(x1));
    (void)memcpy(master->P, P1, sizeof(P1));
    master_recentre(master);
    return TWO_LINK_ARM_OK;
}

int two_link_arm_master_estimate(const two_link_arm_master* master, real x[NX], real P[NXX])
{
    if (!master) {
        return TWO_LINK_ARM_ERR_ARG;
    }
    if (x != NULL) {
        two_link_arm_move_origin(master->x, master->centre, NULL, x);
    }
    if (P != NULL) {
        (void)memcpy(P, master->P, sizeof(master->P));
    }
    return TWO_LINK_ARM_OK;
}
