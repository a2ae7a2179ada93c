/* DO NOT EDIT: dc_motor_link module, generated from template node_replay.c.j2 by dfeif-codegen
 * 0.1.0; regenerate with `codegen build dc_motor_link`. */
/* One camera node: the local derivative-free Kalman filter with packet drops and late
 * measurements (replay), following docs/algorithms.md. Every public function validates and
 * computes into locals first and writes the node only once nothing can fail; each has one exit.
 * The node stores P as its packed upper triangle (NPP reals) and unpacks it only at the API. */
#include <string.h>
#include "dc_motor_link_internal.h"

#define NX DC_MOTOR_LINK_NX
#define NY DC_MOTOR_LINK_NY
#define NW DC_MOTOR_LINK_NW /* the input a prediction takes */
#define NXX (DC_MOTOR_LINK_NX * DC_MOTOR_LINK_NX)
#define NPP 6 /* DC_MOTOR_LINK_NPP */
#define NXP 9 /* a state: x, then P packed */
#define SLOTS (DC_MOTOR_LINK_NMAX + 1)
#define HAS 1u /* the step has a measurement (on time or late) */
#define USED 2u /* the filter history used it (its gain is not zero) */

size_t dc_motor_link_node_size(void)
{
    return sizeof(dc_motor_link_node);
}

size_t dc_motor_link_packet_size(void)
{
    return sizeof(dc_motor_link_packet);
}

/* Step numbers wrap at 2^32, which no ring size divides: a step of the window (k - NMAX .. k + 1)
 * is found by its distance back from k, k - step modulo 2^32, from k's own positions. */

/* Ring slot of a step for x, z and v (NMAX + 1 slots). */
static int slot_of(const dc_motor_link_node* node, uint32_t step)
{
    const uint32_t size = (uint32_t)DC_MOTOR_LINK_NMAX + 1u;
    uint32_t at = ((uint32_t)node->slot + size) - (node->k - step);
    at %= size;
    return (int)at;
}

/* Entry of a step in the flags' history, which reaches CHECK_EVERY - 1 steps further back than
 * the ring so that the P recursion can start from the checkpoint before the oldest slot. */
static int hist_of(const dc_motor_link_node* node, uint32_t step)
{
    uint32_t at = ((uint32_t)node->hist + DC_MOTOR_LINK_NODE_NHIST) - (node->k - step);
    at %= DC_MOTOR_LINK_NODE_NHIST;
    return (int)at;
}

/* Entry of a checkpoint step (a multiple of CHECK_EVERY) in ring_P. */
static int check_of(const dc_motor_link_node* node, uint32_t step)
{
    /* CHECK_EVERY divides 2^32, so k mod CHECK_EVERY does not jump where k wraps */
    uint32_t latest = node->k - (node->k % DC_MOTOR_LINK_NODE_CHECK_EVERY);
    uint32_t back = (latest - step) / DC_MOTOR_LINK_NODE_CHECK_EVERY;
    uint32_t at = ((uint32_t)node->check + DC_MOTOR_LINK_NODE_NCHECK) - back;
    at %= DC_MOTOR_LINK_NODE_NCHECK;
    return (int)at;
}

/* The full symmetric matrix of a packed upper triangle (column by column). */
static void unpack(const real* Pp, real* P)
{
    int i;
    int j;
    for (j = 0; j < NX; j++) {
        for (i = 0; i <= j; i++) {
            real a = Pp[((j * (j + 1)) / 2) + i];
            P[(i * NX) + j] = a;
            P[(j * NX) + i] = a;
        }
    }
}

/* The packed upper triangle of a symmetric matrix. */
static void pack(const real* P, real* Pp)
{
    int i;
    int j;
    for (j = 0; j < NX; j++) {
        for (i = 0; i <= j; i++) {
            Pp[((j * (j + 1)) / 2) + i] = P[(i * NX) + j];
        }
    }
}

/* 1 if a state (x, then P packed) is all finite: the results' one check. The stored inputs were
 * checked at init, and a NaN or infinity in z or v reaches the result's x (NaN * 0 is NaN). The
 * sum is finite only if every term is (an infinity or a NaN survives any sum, and s - s is 0 for
 * a finite s, NaN otherwise): one add per value. Only a sum that overflows on finite terms takes
 * the per-value check. */
static inline int finite_state(const real* xP)
{
    real acc = xP[0];
    int ok = 1;
    acc += xP[1];
    acc += xP[2];
    acc += xP[3];
    acc += xP[4];
    acc += xP[5];
    acc += xP[6];
    acc += xP[7];
    acc += xP[8];
    acc -= acc;
    if (!(acc == (real)0)) {
        ok = dc_motor_link_finite(xP, (size_t)NXP);
    }
    return ok;
}

/* Measurement relative to the node's centre. */
static void centred(const dc_motor_link_node* node, const real* z, real* zc)
{
    int j;
    for (j = 0; j < NY; j++) {
        zc[j] = z[j] - node->centre[j];
    }
}

/* Move output j's centre by whole steps to within half a step of the estimate, and every
 * stored value with it (called before the current step's update). Moving the centre leaves
 * A x + B v unchanged: it only touches the chain heads, and A maps a head-only vector to itself.
 * P does not depend on the centre. */
static void shift_centre(dc_motor_link_node* node, int j, int h, real step, real per)
{
    int s;
    real shift = dc_motor_link_centre_shift(node->post[h], step, per);
    if (shift != (real)0) {
        node->centre[j] += shift;
        node->post[h] -= shift;
        node->pred[h] -= shift;
        for (s = 0; s < SLOTS; s++) {
            node->ring_x[(s * NX) + h] -= shift;
            node->ring_z[(s) + j] -= shift;
        }
        node->ring_z[((int)node->slot) + j] = (real)0; /* the current step's: no z yet */
    }
}

/* Each output's centre within half its step of the estimate x (the node's): a shift only when
 * a head is half a step or more away (the heads and steps are the generator's constants). */
static inline void recentre(dc_motor_link_node* node, const real* x)
{
    if ((x[0] >= 0.0625) || (x[0] <= -0.0625)) {
        shift_centre(node, 0, 0, 0.125, 8.0);
    }
}

/* The innovation e = z - x[heads] of a state (x first), each angle output's wrapped. */
static inline void innovation(const real* x, const real* z, real* e)
{
    e[0] = dc_motor_link_wrap(z[0] - x[0]);
}

/* 1 if all pivots of S are strictly positive (and not NaN). */
static inline int pivots_ok(const real* piv)
{
    return (piv[0] > (real)0) ? 1 : 0;
}

/* Prediction of a state with the input u held (the heads relative to `centre`) and the process
 * noise Q (Q0 packed); 0 or an error code. */
static inline int predict_step(const real* post, const real* u, const real* Q, const real* centre,
                               real* prior)
{
    int rc = DC_MOTOR_LINK_OK;
    (void)dc_motor_link_kern_node_predict(post, u, Q, centre, prior, &prior[NX]);
    if (finite_state(prior) == 0) {
        rc = DC_MOTOR_LINK_ERR_NONFINITE;
    }
    return rc;
}

int dc_motor_link_cov_ok(const real* A)
{
    real L[NXX];
    real d[NX];
    return dc_motor_link_spd_in(A, NX, L, d);
}

int dc_motor_link_in_domain(const real* x)
{
    real F[NY];
    real G[DC_MOTOR_LINK_NYY];
    int ok = 0;
    (void)dc_motor_link_kern_domain(x, F, G);
    if ((dc_motor_link_finite(F, NY) != 0) && (dc_motor_link_finite(G, DC_MOTOR_LINK_NYY) != 0)) {
        ok = 1;
    }
    return ok;
}

int dc_motor_link_node_init(dc_motor_link_node* node, const real x0[NX], const real P0[NXX],
                            const real R[DC_MOTOR_LINK_NYY], const real q[DC_MOTOR_LINK_NQ])
{
    real xP[NXP];
    int i;
    int rc = DC_MOTOR_LINK_OK;
    if ((node == NULL) || (x0 == NULL) || (P0 == NULL) || (R == NULL) || (q == NULL)) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    }
    if ((rc == DC_MOTOR_LINK_OK) &&
        ((dc_motor_link_finite(x0, NX) == 0) || (dc_motor_link_finite(P0, NXX) == 0))) {
        rc = DC_MOTOR_LINK_ERR_NONFINITE;
    }
    if ((rc == DC_MOTOR_LINK_OK) && (dc_motor_link_finite(R, DC_MOTOR_LINK_NYY) == 0)) {
        rc = DC_MOTOR_LINK_ERR_NONFINITE;
    }
    if ((rc == DC_MOTOR_LINK_OK) && (dc_motor_link_finite(q, DC_MOTOR_LINK_NQ) == 0)) {
        rc = DC_MOTOR_LINK_ERR_NONFINITE;
    }
    for (i = 0; (rc == DC_MOTOR_LINK_OK) && (i < DC_MOTOR_LINK_NQ); i++) {
        if (q[i] < (real)0) {
            rc = DC_MOTOR_LINK_ERR_ARG;
        }
    }
    if ((rc == DC_MOTOR_LINK_OK) && (dc_motor_link_spd(R, NY) == 0)) {
        rc = DC_MOTOR_LINK_ERR_SINGULAR;
    }
    /* P0 must be symmetric positive definite */
    if ((rc == DC_MOTOR_LINK_OK) && (dc_motor_link_cov_ok(P0) == 0)) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    }
    /* x0 in the model's domain: else no input predicts out of it (the centre is 0 here) */
    if ((rc == DC_MOTOR_LINK_OK) && (dc_motor_link_in_domain(x0) == 0)) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    }
    if (rc == DC_MOTOR_LINK_OK) {
        (void)memcpy(xP, x0, sizeof(real) * (size_t)NX);
        pack(P0, &xP[NX]);
        (void)memset(node, 0, sizeof(*node));
        node->measured = 1u; /* the prior is of step 0: every step may be replayed */
        (void)memcpy(node->post, xP, sizeof(xP));
        (void)memcpy(node->pred, xP, sizeof(xP));
        (void)memcpy(node->ring_x, x0, sizeof(real) * (size_t)NX);
        /* the checkpoint of step 0 */
        (void)memcpy(node->ring_P, &xP[NX], sizeof(real) * (size_t)NPP);
        (void)memcpy(node->R, R, sizeof(node->R));
        (void)memcpy(node->q, q, sizeof(node->q));
        (void)dc_motor_link_kern_noise(q, node->Qd);
        recentre(node, node->post);
    }
    return rc;
}

/* A node started mid-run holds the prior of step 0 for a later step, perhaps far from the plant
 * (a restart): a replay through that prior alone corrects it by as much, and the held mean over
 * that correction departs from the Phi the master's difference rule assumes (docs/algorithms.md,
 * node). Its window starts at its first measurement. */
int dc_motor_link_node_mid_run(dc_motor_link_node* node)
{
    int rc = DC_MOTOR_LINK_OK;
    if (node == NULL) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    } else if ((node->k != 0u) || (node->updated != 0u)) {
        rc = DC_MOTOR_LINK_ERR_SEQUENCE;
    } else {
        node->measured = 0u;
    }
    return rc;
}

/* A failed update puts step k's prior back (see node_update). */
static void put_back_prior(dc_motor_link_node* node)
{
    (void)memcpy(node->post, node->pred, sizeof(node->post));
    (void)memset(&node->ring_z[(int)node->slot], 0, sizeof(real) * (size_t)NY);
}

/* While step k is not updated, post equals its prior (pred, whose x also equals its ring
 * slot's) and its z slot is 0: the update computes into them in place, and a failure
 * puts the prior back. A step without a measurement keeps its prior. */
int dc_motor_link_node_update(dc_motor_link_node* node, const real z[NY], int gamma)
{
    real piv[NY];
    real e[NY];
    real* zk;
    int rc = DC_MOTOR_LINK_OK;
    if ((node == NULL) || ((gamma != 0) && (gamma != 1)) || ((gamma == 1) && (z == NULL))) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    }
    if ((rc == DC_MOTOR_LINK_OK) && (node->updated != 0u)) {
        rc = DC_MOTOR_LINK_ERR_SEQUENCE;
    }
    if ((rc == DC_MOTOR_LINK_OK) && (gamma == 1)) { /* a non-finite z makes the posterior so */
        zk = &node->ring_z[(int)node->slot];
        centred(node, z, zk);
        innovation(node->pred, zk, e);
        (void)dc_motor_link_kern_update(node->pred, e, node->R, node->post, piv);
        if (pivots_ok(piv) == 0) {
            rc = DC_MOTOR_LINK_ERR_SINGULAR;
        } else if (finite_state(node->post) == 0) {
            rc = DC_MOTOR_LINK_ERR_NONFINITE;
        } else {
            /* a finite posterior */
        }
        if (rc != DC_MOTOR_LINK_OK) {
            put_back_prior(node);
        }
    }
    if (rc == DC_MOTOR_LINK_OK) {
        node->ring_flags[node->hist] = (uint8_t)((gamma == 1) ? (HAS | USED) : 0u);
        node->updated = 1;
        if (gamma == 1) {
            node->health.updates++;
            if (node->measured == 0u) {
                node->measured = 1u;
                node->age = 0u;
            }
        } else {
            node->health.drops++;
        }
    }
    return rc;
}

/* Filter update of one state (x, then P packed) from its prior; 0 or an error code. A step
 * without a measurement (used = 0) keeps its prior. */
static int update_step(const real* prior, const real* z, int used, const real* R, real* post)
{
    real piv[NY];
    real e[NY];
    int rc = DC_MOTOR_LINK_OK;
    if (used != 0) {
        innovation(prior, z, e);
        (void)dc_motor_link_kern_update(prior, e, R, post, piv);
        if (pivots_ok(piv) == 0) {
            rc = DC_MOTOR_LINK_ERR_SINGULAR;
        } else if (finite_state(post) == 0) {
            rc = DC_MOTOR_LINK_ERR_NONFINITE;
        } else {
            /* a finite posterior */
        }
    } else {
        (void)memcpy(post, prior, sizeof(real) * (size_t)NXP);
    }
    return rc;
}

/* The P prior of step j (k - NMAX <= j <= k): the checkpoint of the last multiple of
 * CHECK_EVERY at or before j, carried forward by the filter's own kernels with the flags of the
 * steps between (on x = 0 and z = v = 0: P reads neither, so these are the values the filter had,
 * bit for bit). */
static int prior_P(const dc_motor_link_node* node, uint32_t j, real* prior)
{
    real post[NXP];
    real zero[NY];
    uint32_t s = j - (j % DC_MOTOR_LINK_NODE_CHECK_EVERY);
    int rc = DC_MOTOR_LINK_OK;
    (void)memset(prior, 0, sizeof(real) * (size_t)NX);
    (void)memset(zero, 0, sizeof(zero));
    (void)memcpy(&prior[NX], &node->ring_P[check_of(node, s) * NPP], sizeof(real) * (size_t)NPP);
    while ((rc == DC_MOTOR_LINK_OK) && (s != j)) { /* s <= j, modulo 2^32 */
        int used = 0;
        if ((node->ring_flags[hist_of(node, s)] & USED) != 0u) {
            used = 1;
        }
        rc = update_step(prior, zero, used, node->R, post);
        if (rc == DC_MOTOR_LINK_OK) {
            /* the covariance alone: the held mean at x = 0 may leave the model's domain */
            (void)dc_motor_link_kern_node_predict_P(&post[NX], node->Qd, &prior[NX]);
            if (dc_motor_link_finite(&prior[NX], (size_t)NPP) == 0) {
                rc = DC_MOTOR_LINK_ERR_NONFINITE;
            }
        }
        s++;
    }
    return rc;
}

/* Re-run steps j0..k in one pass: the update of each step from its prior (step j0 with the late
 * z), then the prediction into the next slot, written in place, and each checkpoint passed
 * rewritten; returns the posterior of step k. On a failure the slots' x and the checkpoints are
 * put back from the copies taken on the way. */
static int replay(dc_motor_link_node* node, uint32_t j0, const real* zlate, real* post)
{
    real old_x[DC_MOTOR_LINK_NMAX * NX];
    real old_P[DC_MOTOR_LINK_NODE_NCHECK_REALS];
    real prior[NXP]; /* step j's: x as its slot holds it, P carried */
    uint32_t j = j0;
    const uint32_t stop = node->k + 1u; /* modulo 2^32: j reaches it after k - j0 + 1 steps */
    uint32_t written = 0u; /* priors' x rewritten so far: slots j0 + 1 .. j0 + written */
    int checks = 0; /* checkpoints rewritten so far, from the first multiple after j0 */
    uint32_t first;
    uint32_t i;
    int c;
    int rc = prior_P(node, j0, prior);
    (void)memcpy(prior, &node->ring_x[slot_of(node, j0) * NX], sizeof(real) * (size_t)NX);
    while ((rc == DC_MOTOR_LINK_OK) && (j != stop)) {
        int slot = slot_of(node, j);
        real* xnext = &node->ring_x[slot_of(node, j + 1u) * NX];
        const real* z = (j == j0) ? zlate : &node->ring_z[slot];
        int used = 1; /* the late step, and the steps the history used */
        if ((j != j0) && ((node->ring_flags[hist_of(node, j)] & USED) == 0u)) {
            used = 0;
        }
        rc = update_step(prior, z, used, node->R, post);
        if ((rc == DC_MOTOR_LINK_OK) && (j != node->k)) {
            (void)memcpy(&old_x[written * (uint32_t)NX], xnext, sizeof(real) * (size_t)NX);
            written++;
            rc = predict_step(post, &node->ring_v[slot], node->Qd, node->centre, prior);
            if (rc == DC_MOTOR_LINK_OK) {
                (void)memcpy(xnext, prior, sizeof(real) * (size_t)NX);
            }
            if ((rc == DC_MOTOR_LINK_OK) && (((j + 1u) % DC_MOTOR_LINK_NODE_CHECK_EVERY) == 0u)) {
                real* cp = &node->ring_P[check_of(node, j + 1u) * NPP];
                (void)memcpy(&old_P[checks * NPP], cp, sizeof(real) * (size_t)NPP);
                checks++;
                (void)memcpy(cp, &prior[NX], sizeof(real) * (size_t)NPP);
            }
        }
        j++;
    }
    if (rc != DC_MOTOR_LINK_OK) {
        first = j0 - (j0 % DC_MOTOR_LINK_NODE_CHECK_EVERY); /* the first checkpoint after j0 */
        first += DC_MOTOR_LINK_NODE_CHECK_EVERY;
        for (i = 0u; i < written; i++) {
            (void)memcpy(&node->ring_x[slot_of(node, j0 + 1u + i) * NX], &old_x[i * (uint32_t)NX],
                         sizeof(real) * (size_t)NX);
        }
        for (c = 0; c < checks; c++) {
            (void)memcpy(&node->ring_P[check_of(node, first) * NPP], &old_P[c * NPP],
                         sizeof(real) * (size_t)NPP);
            first += DC_MOTOR_LINK_NODE_CHECK_EVERY;
        }
    }
    return rc;
}

int dc_motor_link_node_update_delayed(dc_motor_link_node* node, const real z_abs[NY], int32_t lag)
{
    real post[NXP];
    real z[NY];
    uint32_t N = 0u;
    int hist = 0;
    int rc = DC_MOTOR_LINK_OK;
    if ((node == NULL) || (z_abs == NULL)) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    }
    if ((rc == DC_MOTOR_LINK_OK) && (node->updated == 0u)) {
        rc = DC_MOTOR_LINK_ERR_SEQUENCE;
    }
    if ((rc == DC_MOTOR_LINK_OK) && (dc_motor_link_finite(z_abs, NY) == 0)) {
        rc = DC_MOTOR_LINK_ERR_NONFINITE;
    }
    if ((rc == DC_MOTOR_LINK_OK) && ((lag < 1) || (lag > DC_MOTOR_LINK_NMAX))) {
        node->health.late_rejected++;
        rc = DC_MOTOR_LINK_ERR_LAG;
    }
    /* before step 0, or (started mid-run) before the first measurement, which holds the start-up
     * prior alone */
    if ((rc == DC_MOTOR_LINK_OK) && ((node->measured == 0u) || ((uint32_t)lag > node->age))) {
        node->health.late_rejected++;
        rc = DC_MOTOR_LINK_ERR_LAG;
    }
    if (rc == DC_MOTOR_LINK_OK) {
        centred(node, z_abs, z);
        N = (uint32_t)lag;
        hist = hist_of(node, node->k - N);
        if ((node->ring_flags[hist] & HAS) != 0u) {
            node->health.late_rejected++;
            rc = DC_MOTOR_LINK_ERR_DUPLICATE;
        }
    }
    if (rc == DC_MOTOR_LINK_OK) {
        rc = replay(node, node->k - N, z, post);
    }
    if (rc == DC_MOTOR_LINK_OK) {
        (void)memcpy(&node->ring_z[slot_of(node, node->k - N)], z, sizeof(real) * (size_t)NY);
        node->ring_flags[hist] = (uint8_t)(HAS | USED);
    }
    if (rc == DC_MOTOR_LINK_OK) {
        (void)memcpy(node->post, post, sizeof(post));
        node->health.late_applied++;
    }
    return rc;
}

int dc_motor_link_node_predict(dc_motor_link_node* node, const real input[NW])
{
    const real* v = input;
    real next[NXP];
    int slot;
    uint32_t hist;
    uint32_t check;
    int rc = DC_MOTOR_LINK_OK;
    if ((node == NULL) || (v == NULL)) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    }
    if ((rc == DC_MOTOR_LINK_OK) && (node->updated == 0u)) {
        rc = DC_MOTOR_LINK_ERR_SEQUENCE;
    }
    if (rc == DC_MOTOR_LINK_OK) { /* a non-finite v makes the prediction so */
        rc = predict_step(node->post, v, node->Qd, node->centre, next);
    }
    if (rc == DC_MOTOR_LINK_OK) {
        slot = (int)node->slot;
        (void)memcpy(&node->ring_v[slot], v, sizeof(real) * (size_t)NW);
        node->k++;
        slot = (slot == DC_MOTOR_LINK_NMAX) ? 0 : (slot + 1);
        node->slot = (uint16_t)slot;
        hist = (uint32_t)node->hist + 1u;
        node->hist = (uint16_t)((hist == DC_MOTOR_LINK_NODE_NHIST) ? 0u : hist);
        (void)memcpy(&node->ring_x[slot * NX], next, sizeof(real) * (size_t)NX);
        if (node->age < DC_MOTOR_LINK_NODE_NHIST) {
            node->age++;
        }
        if ((node->k % DC_MOTOR_LINK_NODE_CHECK_EVERY) == 0u) {
            check = (uint32_t)node->check + 1u;
            node->check = (uint16_t)((check == DC_MOTOR_LINK_NODE_NCHECK) ? 0u : check);
            (void)memcpy(&node->ring_P[(int)node->check * NPP], &next[NX],
                         sizeof(real) * (size_t)NPP);
        }
        (void)memset(&node->ring_z[slot], 0, sizeof(real) * (size_t)NY);
        (void)memcpy(node->post, next, sizeof(next));
        (void)memcpy(node->pred, next, sizeof(next));
        node->updated = 0;
        recentre(node, next);
    }
    return rc;
}

int dc_motor_link_node_estimate(const dc_motor_link_node* node, real x[NX], real P[NXX])
{
    int rc = DC_MOTOR_LINK_OK;
    if (node == NULL) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    } else {
        if (x != NULL) {
            dc_motor_link_move_origin(node->post, node->centre, NULL, x);
        }
        if (P != NULL) {
            unpack(&node->post[NX], P);
        }
    }
    return rc;
}

int dc_motor_link_node_information(const dc_motor_link_node* node, real Y[NXX], real y[NX])
{
    real Yl[NXX];
    real yl[NX];
    real piv[NX];
    real origin[NX];
    real x[NX];
    real P[NXX];
    int rc = DC_MOTOR_LINK_OK;
    if (node == NULL) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    }
    if (rc == DC_MOTOR_LINK_OK) {
        (void)memset(origin, 0, sizeof(origin));
        dc_motor_link_move_origin(node->post, node->centre, NULL, x);
        unpack(&node->post[NX], P);
        (void)dc_motor_link_kern_info(x, P, origin, Yl, yl, piv);
        if (dc_motor_link_positive(piv, NX) == 0) {
            rc = DC_MOTOR_LINK_ERR_SINGULAR;
        }
    }
    if ((rc == DC_MOTOR_LINK_OK) &&
        ((dc_motor_link_finite(Yl, NXX) == 0) || (dc_motor_link_finite(yl, NX) == 0))) {
        rc = DC_MOTOR_LINK_ERR_NONFINITE;
    }
    if (rc == DC_MOTOR_LINK_OK) {
        if (Y != NULL) {
            (void)memcpy(Y, Yl, sizeof(Yl));
        }
        if (y != NULL) {
            (void)memcpy(y, yl, sizeof(yl));
        }
    }
    return rc;
}

int dc_motor_link_node_packet(const dc_motor_link_node* node, dc_motor_link_packet* packet)
{
    int rc = DC_MOTOR_LINK_OK;
    if ((node == NULL) || (packet == NULL)) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    } else {
        packet->step = node->k;
        (void)memcpy(packet->centre, node->centre, sizeof(packet->centre));
        (void)memcpy(packet->x, node->post, sizeof(packet->x));
        unpack(&node->post[NX], packet->P);
        (void)memcpy(packet->x_pred, node->pred, sizeof(packet->x_pred));
        unpack(&node->pred[NX], packet->P_pred);
    }
    return rc;
}

int dc_motor_link_node_health(const dc_motor_link_node* node, dc_motor_link_health* health)
{
    int rc = DC_MOTOR_LINK_OK;
    if ((node == NULL) || (health == NULL)) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    } else {
        *health = node->health;
    }
    return rc;
}
