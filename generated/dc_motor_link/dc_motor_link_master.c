/* DO NOT EDIT: dc_motor_link module, generated from template master_difference.c.j2 by
 * dfeif-codegen 0.1.0; regenerate with `codegen build dc_motor_link`. */
/* The master: predicts stale packets to the current step, fuses the nodes' estimates in
 * information form (difference rule) and keeps its own prediction, following
 * docs/algorithms.md. Computes into locals; writes the master only when nothing can fail.
 * Finiteness is checked on the inputs, on the information gathered and on the results; the
 * kernels' pivots after each factorisation. */
#include <string.h>
#include "dc_motor_link_internal.h"

#define NX DC_MOTOR_LINK_NX
#define NY DC_MOTOR_LINK_NY
#define NW DC_MOTOR_LINK_NW /* the input a prediction takes */
#define NXX (DC_MOTOR_LINK_NX * DC_MOTOR_LINK_NX)
/* a symmetric matrix's upper triangle, packed row by row */
#define NXP ((DC_MOTOR_LINK_NX * (DC_MOTOR_LINK_NX + 1)) / 2)
#define NNODES DC_MOTOR_LINK_NNODES
#define NMAX DC_MOTOR_LINK_NMAX
/* pivots of two factorisations per kernel */
#define NPIV (2 * NX)

size_t dc_motor_link_master_size(void)
{
    return sizeof(dc_motor_link_master);
}

/* Where step j's input starts in master->v: by its distance back from k (k - NMAX <= j <= k),
 * as step numbers wrap at 2^32, which NMAX need not divide. */
static size_t input_at(const dc_motor_link_master* master, uint32_t step)
{
    uint32_t slot = (master->vslot + (uint32_t)NMAX - (master->k - step)) % (uint32_t)NMAX;
    return (size_t)slot;
}

/* One prediction of (x, P) with the input of one step (the heads relative to `centre`) and the
 * process noise (Q0 packed, Qd). */
static int master_step(const real* x, const real* P, const real* v, const real* noise,
                       const real* centre, real* x1, real* P1)
{
    int rc = DC_MOTOR_LINK_OK;
    (void)dc_motor_link_kern_predict(x, P, v, noise, centre, x1, P1);
    if ((dc_motor_link_finite(x1, NX) == 0) || (dc_motor_link_finite(P1, NXX) == 0)) {
        rc = DC_MOTOR_LINK_ERR_NONFINITE;
    }
    return rc;
}

/* Move output j's centre (head h) by whole steps to within half a step of the estimate. */
static void master_shift(dc_motor_link_master* master, int j, int h, real step, real per)
{
    real shift = dc_motor_link_centre_shift(master->x[h], step, per);
    master->centre[j] += shift;
    master->x[h] -= shift;
    master->x_prior[h] -= shift;
}

/* Every output's centre moved, each in its own step (as the node does). */
static void master_recentre(dc_motor_link_master* master)
{
    master_shift(master, 0, 0, 0.125, 8.0);
}

/* An estimate (x_in, P_in) of step `step`, stored relative to `centre`, at the master's step
 * and relative to its centre: x into x, P_in itself when it is of this step, else predicted
 * step by step with the stored inputs (the held mean is not linear: no one-step form) into
 * P_buf; *P_out says which. `effect` is not used. */
static inline int bring(const dc_motor_link_master* master, uint32_t step, const real* centre,
                        const real* x_in, const real* P_in, const real* effect, real* x,
                        real* P_buf, const real** P_out)
{
    real x1[NX];
    real P1[NXX];
    uint32_t s;
    int rc = DC_MOTOR_LINK_OK;
    (void)effect;
    dc_motor_link_move_origin(x_in, centre, master->centre, x);
    *P_out = P_in;
    /* step <= k, modulo 2^32 */
    for (s = step; (s != master->k) && (rc == DC_MOTOR_LINK_OK); s++) {
        rc = master_step(x, *P_out, &master->v[input_at(master, s)], master->Qd, master->centre, x1,
                         P1);
        (void)memcpy(x, x1, sizeof(x1));
        (void)memcpy(P_buf, P1, sizeof(P1));
        *P_out = P_buf;
    }
    return rc;
}

/* x's angle heads moved by whole turns (turns[j], 0 for the other outputs). */
static void turn(real* x, const real turns[NY])
{
    int j;
    for (j = 0; j < NY; j++) {
        x[dc_motor_link_heads[j]] -= turns[j];
    }
}

/* Each angle head of a node's x (relative to the master's centre) moved by whole turns to the
 * branch nearest the master's prediction, the turns into turns[] for the node's x_pred: 6.383
 * and 0.1 are the same angle and fuse as such (docs/algorithms.md, master). */
static void on_branch(const dc_motor_link_master* master, real* x, real turns[NY])
{
    real d;
    (void)memset(turns, 0, sizeof(real[NY]));
    d = x[0] - master->x_prior[0];
    turns[0] = d - dc_motor_link_wrap(d);
    turn(x, turns);
}

/* acc + sum of a[i] * 0: 0 while every value is finite, NaN once one is infinite or NaN
 * (v * 0 is NaN for those, and a NaN stays in the sum). One test at the end instead of a
 * branch per value. */
static inline real zero_sum(const real* a, int n, real acc)
{
    real sum = acc;
    int i;
    for (i = 0; i < n; i++) {
        sum += a[i] * (real)0;
    }
    return sum;
}

/* 1 if the probe of zero_sum is 0 (all values finite). */
static inline int probe_ok(real probe)
{
    return (probe == (real)0) ? 1 : 0;
}

/* A packet's numbers are all finite (as zero_sum, two arrays per pass). */
static inline int packet_finite(const dc_motor_link_packet* pk)
{
    real probe = zero_sum(pk->centre, NY, (real)0);
    int i;
    for (i = 0; i < NXX; i++) {
        probe += (pk->P[i] * (real)0) + (pk->P_pred[i] * (real)0);
    }
    for (i = 0; i < NX; i++) {
        probe += (pk->x[i] * (real)0) + (pk->x_pred[i] * (real)0);
    }
    return probe_ok(probe);
}

/* Both arrays finite. */
static inline int pair_finite(const real* a, int na, const real* b, int nb)
{
    return probe_ok(zero_sum(b, nb, zero_sum(a, na, (real)0)));
}

/* present[] holds 0 or 1 only. */
static int present_ok(const uint8_t present[NNODES])
{
    int i;
    int ok = 1;
    for (i = 0; i < NNODES; i++) {
        if (present[i] > 1u) {
            ok = 0;
        }
    }
    return ok;
}

/* Packet pk of node i is not newer than the last one fused from that node (modulo 2^32): that
 * one's gain, taken over a gap, covered its step. */
static int covered(const dc_motor_link_master* master, int i, const dc_motor_link_packet* pk)
{
    int out = 0;
    if ((master->last_valid[i] != 0u) && ((pk->step - master->last_step[i] - 1u) >= 0x7FFFFFFFu)) {
        out = 1;
    }
    return out;
}

/* Where packets of node i were lost since the last one fused from it (of step j, within the
 * stored inputs), that packet's estimate brought to the current step replaces the node's own
 * prediction (xp, *Ppk) as what the gain is taken over: the gain then holds every frame the node
 * used since j (a channel filter, docs/algorithms.md). Not where it is far better informed on a
 * diagonal entry than the node's own prediction (below 0.5 of it): after a restart the
 * node's own holds less. */
static int channel(const dc_motor_link_master* master, int i, const dc_motor_link_packet* pk,
                   real* xp, real* Pc, const real** Ppk)
{
    real xc[NX];
    real effect[NX];
    const real* Pk = Pc;
    uint32_t j = master->last_step[i];
    int better = 0;
    int d;
    int rc = DC_MOTOR_LINK_OK;
    if ((master->last_valid[i] != 0u) && ((pk->step - j) > 1u) &&
        ((master->k - j) <= master->age)) {
        (void)memset(effect, 0, sizeof(effect)); /* not used by the held predictor's bring */
        rc = bring(master, j, &master->last_centre[i], &master->last_x[i * NX],
                   &master->last_P[i * NXX], effect, xc, Pc, &Pk);
        /* without a restart Pk >= *Ppk on the diagonal but for rounding (equal: no frame in the
         * gap), so the test sits far from 1 (constants.CHANNEL_RESTART_RATIO) */
        for (d = 0; d < NX; d++) {
            if (Pk[(d * NX) + d] < ((*Ppk)[(d * NX) + d] * 0.5)) {
                better = 1; /* the node's own prediction holds less: it restarted */
            }
        }
        if ((rc == DC_MOTOR_LINK_OK) && (better == 0)) {
            (void)memcpy(xp, xc, sizeof(xc));
            *Ppk = Pk;
        }
    }
    return rc;
}

int dc_motor_link_packet_check(const dc_motor_link_packet* pk)
{
    int rc = DC_MOTOR_LINK_OK;
    int i;
    if ((dc_motor_link_cov_ok(pk->P) == 0) || (dc_motor_link_cov_ok(pk->P_pred) == 0)) {
        rc = DC_MOTOR_LINK_ERR_WIRE_COVARIANCE;
    }
    /* an update only shrinks P: P_ii <= P_pred_ii, to the rounding of the node's subtraction */
    for (i = 0; (rc == DC_MOTOR_LINK_OK) && (i < NX); i++) {
        real d = pk->P_pred[(i * NX) + i];
        real slack = d * 1.4210854715202004e-14;
        if (pk->P[(i * NX) + i] > (d + slack)) {
            rc = DC_MOTOR_LINK_ERR_WIRE_GAIN;
        }
    }
    return rc;
}

int dc_motor_link_master_init(dc_motor_link_master* master, const real x0[NX], const real P0[NXX],
                              const real q[DC_MOTOR_LINK_NQ])
{
    int i;
    int rc = DC_MOTOR_LINK_OK;
    if ((master == NULL) || (x0 == NULL) || (P0 == NULL) || (q == NULL)) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    } else if ((dc_motor_link_finite(x0, NX) == 0) || (dc_motor_link_finite(P0, NXX) == 0) ||
               (dc_motor_link_finite(q, DC_MOTOR_LINK_NQ) == 0)) {
        rc = DC_MOTOR_LINK_ERR_NONFINITE;
    } else {
        for (i = 0; i < DC_MOTOR_LINK_NQ; i++) {
            if (q[i] < (real)0) {
                rc = DC_MOTOR_LINK_ERR_ARG;
            }
        }
        /* P0 must be symmetric positive definite */
        if ((rc == DC_MOTOR_LINK_OK) && (dc_motor_link_cov_ok(P0) == 0)) {
            rc = DC_MOTOR_LINK_ERR_ARG;
        }
        /* x0 in the model's domain: else no input predicts out of it (the centre is 0 here) */
        if ((rc == DC_MOTOR_LINK_OK) && (dc_motor_link_in_domain(x0) == 0)) {
            rc = DC_MOTOR_LINK_ERR_ARG;
        }
    }
    if (rc == DC_MOTOR_LINK_OK) {
        (void)memset(master, 0, sizeof(*master));
        (void)memcpy(master->x, x0, sizeof(master->x));
        (void)memcpy(master->P, P0, sizeof(master->P));
        (void)memcpy(master->x_prior, x0, sizeof(master->x_prior));
        (void)memcpy(master->P_prior, P0, sizeof(master->P_prior));
        (void)memcpy(master->q, q, sizeof(master->q));
        (void)dc_motor_link_kern_noise(q, master->Qd);
        master_recentre(master);
    }
    return rc;
}

int dc_motor_link_master_fuse(dc_motor_link_master* master,
                              const dc_motor_link_packet packets[NNODES],
                              const uint8_t present[NNODES])
{
    return dc_motor_link_master_fuse_try(master, packets, present, 1);
}

int dc_motor_link_master_fuse_try(dc_motor_link_master* master,
                                  const dc_motor_link_packet packets[NNODES],
                                  const uint8_t present[NNODES], int commit)
{
    real x[NX];
    real P[NXX];
    real Yacc[NXP];
    real yacc[NX];
    real piv[NPIV];
    real effect[NX];
    const real* Pk = P;
    real turns[NY];
    real xp[NX];
    real Pp[NXX];
    real Pc[NXX];
    const real* Ppk = Pp;
    real dY[NXP];
    real dy[NX];
    uint8_t took[NNODES];
    int d;
    uint32_t used = 0u;
    uint32_t stale = 0u;
    uint32_t ignored = 0u;
    int i;
    int rc = DC_MOTOR_LINK_OK;
    if ((master == NULL) || (packets == NULL) || (present == NULL)) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    } else if (present_ok(present) == 0) { /* the master is changed only after the packets */
        rc = DC_MOTOR_LINK_ERR_ARG;
    } else {
        (void)memset(Yacc, 0, sizeof(Yacc));
        (void)memset(yacc, 0, sizeof(yacc));
        (void)memset(took, 0, sizeof(took));
    }
    for (i = 0; (i < NNODES) && (rc == DC_MOTOR_LINK_OK); i++) {
        const dc_motor_link_packet* pk = &packets[i];
        if (present[i] == 0u) {
            /* absent: left out */
        } else if ((master->k - pk->step) > master->age) { /* modulo 2^32: also the future's */
            ignored++;
        } else if (packet_finite(pk) == 0) {
            rc = DC_MOTOR_LINK_ERR_NONFINITE;
        } else if (dc_motor_link_packet_check(pk) != DC_MOTOR_LINK_OK) {
            /* P or P_pred not SPD, or P above P_pred (difference rule) */
            rc = DC_MOTOR_LINK_ERR_SINGULAR;
        } else if (covered(master, i, pk) != 0) {
            ignored++;
        } else {
            (void)memset(effect, 0, sizeof(effect)); /* not used by the held predictor's bring */
            rc = bring(master, pk->step, pk->centre, pk->x, pk->P, effect, x, P, &Pk);
            on_branch(master, x, turns);
            if (rc == DC_MOTOR_LINK_OK) {
                rc = bring(master, pk->step, pk->centre, pk->x_pred, pk->P_pred, effect, xp, Pp,
                           &Ppk);
            }
            if (rc == DC_MOTOR_LINK_OK) {
                rc = channel(master, i, pk, xp, Pc, &Ppk);
                turn(xp, turns); /* the turns of the node's x: its gain is kept */
            }
            if (rc == DC_MOTOR_LINK_OK) {
                (void)dc_motor_link_kern_master_gain(x, Pk, xp, Ppk, master->x, dY, dy, piv);
                if (dc_motor_link_positive(piv, NPIV) == 0) {
                    rc = DC_MOTOR_LINK_ERR_SINGULAR;
                }
            }
            if (rc == DC_MOTOR_LINK_OK) {
                for (d = 0; d < NXP; d++) {
                    Yacc[d] += dY[d];
                }
                for (d = 0; d < NX; d++) {
                    yacc[d] += dy[d];
                }
                took[i] = 1u;
            }
            if (rc == DC_MOTOR_LINK_OK) {
                used++;
                if (pk->step != master->k) {
                    stale++;
                }
            }
        }
    }
    if (rc != DC_MOTOR_LINK_OK) {
        /* refused: the master is left as it was */
    } else if (used == 0u) {
        /* information adds: the estimate so far (the prediction, or an earlier call's result) */
        (void)memcpy(x, master->x, sizeof(x));
        (void)memcpy(P, master->P, sizeof(P));
    } else {
        if (pair_finite(Yacc, NXP, yacc, NX) == 0) {
            rc = DC_MOTOR_LINK_ERR_NONFINITE;
        } else {
            (void)dc_motor_link_kern_fuse_finish(master->P, Yacc, yacc, master->x, x, P, piv);
        }
        if ((rc == DC_MOTOR_LINK_OK) && (dc_motor_link_positive(piv, NPIV) == 0)) {
            rc = DC_MOTOR_LINK_ERR_SINGULAR;
        }
        if ((rc == DC_MOTOR_LINK_OK) && (pair_finite(x, NX, P, NXX) == 0)) {
            rc = DC_MOTOR_LINK_ERR_NONFINITE;
        }
    }
    if ((rc == DC_MOTOR_LINK_OK) && (commit != 0)) {
        (void)memcpy(master->x, x, sizeof(x));
        (void)memcpy(master->P, P, sizeof(P));
        master->health.fusions++;
        master->health.packets_used += used;
        master->health.packets_stale += stale;
        master->health.packets_ignored += ignored;
        for (i = 0; i < NNODES; i++) {
            if (took[i] != 0u) {
                master->last_step[i] = packets[i].step;
                (void)memcpy(&master->last_centre[i], packets[i].centre, sizeof(real[NY]));
                (void)memcpy(&master->last_x[i * NX], packets[i].x, sizeof(real[NX]));
                (void)memcpy(&master->last_P[i * NXX], packets[i].P, sizeof(real[NXX]));
                master->last_valid[i] = 1u;
            }
        }
    }
    return rc;
}

int dc_motor_link_master_predict(dc_motor_link_master* master, const real input[NW])
{
    const real* v = input;
    real x1[NX];
    real P1[NXX];
    int rc = DC_MOTOR_LINK_OK;
    if ((master == NULL) || (v == NULL)) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    } else if (dc_motor_link_finite(v, NW) == 0) {
        rc = DC_MOTOR_LINK_ERR_NONFINITE;
    } else {
        rc = master_step(master->x, master->P, v, master->Qd, master->centre, x1, P1);
    }
    if (rc == DC_MOTOR_LINK_OK) {
        (void)memcpy(&master->v[input_at(master, master->k)], v, sizeof(real[NW]));
        master->k++;
        master->vslot = ((master->vslot + 1u) == (uint32_t)NMAX) ? 0u : (master->vslot + 1u);
        if (master->age < (uint32_t)NMAX) {
            master->age++;
        }
        (void)memcpy(master->x_prior, x1, sizeof(x1));
        (void)memcpy(master->P_prior, P1, sizeof(P1));
        (void)memcpy(master->x, x1, sizeof(x1));
        (void)memcpy(master->P, P1, sizeof(P1));
        master_recentre(master);
    }
    return rc;
}

int dc_motor_link_master_estimate(const dc_motor_link_master* master, real x[NX], real P[NXX])
{
    int rc = DC_MOTOR_LINK_OK;
    if (master == NULL) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    } else {
        if (x != NULL) {
            dc_motor_link_move_origin(master->x, master->centre, NULL, x);
        }
        if (P != NULL) {
            (void)memcpy(P, master->P, sizeof(master->P));
        }
    }
    return rc;
}
