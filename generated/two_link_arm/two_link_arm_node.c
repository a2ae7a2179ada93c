/* DO NOT EDIT: two_link_arm module, generated from template node_replay.c.j2 by dfeif-codegen
 * 0.1.0; regenerate with `codegen build two_link_arm`. */
/* One camera node: the local derivative-free Kalman filter with packet drops and late
 * measurements (replay), following docs/algorithms.md. Every public function validates and
 * computes into locals first and writes the node only once nothing can fail; each has one exit.
 * The node stores P as its packed upper triangle (NPP reals) and unpacks it only at the API. */
#include <string.h>
#include "two_link_arm_internal.h"

#define NX TWO_LINK_ARM_NX
#define NY TWO_LINK_ARM_NY
#define NW TWO_LINK_ARM_NW /* the input a prediction takes */
#define NXX (TWO_LINK_ARM_NX * TWO_LINK_ARM_NX)
#define NPP 21 /* TWO_LINK_ARM_NPP */
#define NXP 27 /* a state: x, then P packed */
#define SLOTS (TWO_LINK_ARM_NMAX + 1)
#define HAS 1u /* the step has a measurement (on time or late) */
#define USED 2u /* the filter history used it (its gain is not zero) */

size_t two_link_arm_node_size(void)
{
    return sizeof(two_link_arm_node);
}

size_t two_link_arm_packet_size(void)
{
    return sizeof(two_link_arm_packet);
}

/* Step numbers wrap at 2^32, which no ring size divides: a step of the window (k - NMAX .. k + 1)
 * is found by its distance back from k, k - step modulo 2^32, from k's own positions. */

/* Ring slot of a step for x, z and v (NMAX + 1 slots). */
static int slot_of(const two_link_arm_node* node, uint32_t step)
{
    const uint32_t size = (uint32_t)TWO_LINK_ARM_NMAX + 1u;
    uint32_t at = ((uint32_t)node->slot + size) - (node->k - step);
    at %= size;
    return (int)at;
}

/* Entry of a step in the flags' history, which reaches CHECK_EVERY - 1 steps further back than
 * the ring so that the P recursion can start from the checkpoint before the oldest slot. */
static int hist_of(const two_link_arm_node* node, uint32_t step)
{
    uint32_t at = ((uint32_t)node->hist + TWO_LINK_ARM_NODE_NHIST) - (node->k - step);
    at %= TWO_LINK_ARM_NODE_NHIST;
    return (int)at;
}

/* Entry of a checkpoint step (a multiple of CHECK_EVERY) in ring_P. */
static int check_of(const two_link_arm_node* node, uint32_t step)
{
    /* CHECK_EVERY divides 2^32, so k mod CHECK_EVERY does not jump where k wraps */
    uint32_t latest = node->k - (node->k % TWO_LINK_ARM_NODE_CHECK_EVERY);
    uint32_t back = (latest - step) / TWO_LINK_ARM_NODE_CHECK_EVERY;
    uint32_t at = ((uint32_t)node->check + TWO_LINK_ARM_NODE_NCHECK) - back;
    at %= TWO_LINK_ARM_NODE_NCHECK;
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
    acc += xP[9];
    acc += xP[10];
    acc += xP[11];
    acc += xP[12];
    acc += xP[13];
    acc += xP[14];
    acc += xP[15];
    acc += xP[16];
    acc += xP[17];
    acc += xP[18];
    acc += xP[19];
    acc += xP[20];
    acc += xP[21];
    acc += xP[22];
    acc += xP[23];
    acc += xP[24];
    acc += xP[25];
    acc += xP[26];
    acc -= acc;
    if (!(acc == (real)0)) {
        ok = two_link_arm_finite(xP, (size_t)NXP);
    }
    return ok;
}

/* Measurement relative to the node's centre. */
static void centred(const two_link_arm_node* node, const real* z, real* zc)
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
static void shift_centre(two_link_arm_node* node, int j, int h, real step, real per)
{
    int s;
    real shift = two_link_arm_centre_shift(node->post[h], step, per);
    if (shift != (real)0) {
        node->centre[j] += shift;
        node->post[h] -= shift;
        node->pred[h] -= shift;
        for (s = 0; s < SLOTS; s++) {
            node->ring_x[(s * NX) + h] -= shift;
            node->ring_z[(s * NY) + j] -= shift;
        }
        node->ring_z[((int)node->slot * NY) + j] = (real)0; /* the current step's: no z yet */
    }
}

/* Each output's centre within half its step of the estimate x (the node's): a shift only when
 * a head is half a step or more away (the heads and steps are the generator's constants). */
static inline void recentre(two_link_arm_node* node, const real* x)
{
    if ((x[0] >= 0.0625) || (x[0] <= -0.0625)) {
        shift_centre(node, 0, 0, 0.125, 8.0);
    }
    if ((x[3] >= 0.0625) || (x[3] <= -0.0625)) {
        shift_centre(node, 1, 3, 0.125, 8.0);
    }
}

/* The innovation e = z - x[heads] of a state (x first), each angle output's wrapped. */
static inline void innovation(const real* x, const real* z, real* e)
{
    e[0] = two_link_arm_wrap(z[0] - x[0]);
    e[1] = two_link_arm_wrap(z[1] - x[3]);
}

/* 1 if all pivots of S are strictly positive (and not NaN). */
static inline int pivots_ok(const real* piv)
{
    return two_link_arm_positive(piv, NY);
}

/* Prediction of a state with the input u held (the heads relative to `centre`) and the process
 * noise Q (Q0 packed); 0 or an error code. */
static inline int predict_step(const real* post, const real* u, const real* Q, const real* centre,
                               real* prior)
{
    int rc = TWO_LINK_ARM_OK;
    (void)two_link_arm_kern_node_predict(post, u, Q, centre, prior, &prior[NX]);
    if (finite_state(prior) == 0) {
        rc = TWO_LINK_ARM_ERR_NONFINITE;
    }
    return rc;
}

int two_link_arm_cov_ok(const real* A)
{
    real L[NXX];
    real d[NX];
    return two_link_arm_spd_in(A, NX, L, d);
}

int two_link_arm_in_domain(const real* x)
{
    real F[NY];
    real G[TWO_LINK_ARM_NYY];
    int ok = 0;
    (void)two_link_arm_kern_domain(x, F, G);
    if ((two_link_arm_finite(F, NY) != 0) && (two_link_arm_finite(G, TWO_LINK_ARM_NYY) != 0)) {
        ok = 1;
    }
    return ok;
}

int two_link_arm_node_init(two_link_arm_node* node, const real x0[NX], const real P0[NXX],
                           const real R[TWO_LINK_ARM_NYY], const real q[TWO_LINK_ARM_NQ])
{
    real xP[NXP];
    int i;
    int rc = TWO_LINK_ARM_OK;
    if ((node == NULL) || (x0 == NULL) || (P0 == NULL) || (R == NULL) || (q == NULL)) {
        rc = TWO_LINK_ARM_ERR_ARG;
    }
    if ((rc == TWO_LINK_ARM_OK) &&
        ((two_link_arm_finite(x0, NX) == 0) || (two_link_arm_finite(P0, NXX) == 0))) {
        rc = TWO_LINK_ARM_ERR_NONFINITE;
    }
    if ((rc == TWO_LINK_ARM_OK) && (two_link_arm_finite(R, TWO_LINK_ARM_NYY) == 0)) {
        rc = TWO_LINK_ARM_ERR_NONFINITE;
    }
    if ((rc == TWO_LINK_ARM_OK) && (two_link_arm_finite(q, TWO_LINK_ARM_NQ) == 0)) {
        rc = TWO_LINK_ARM_ERR_NONFINITE;
    }
    for (i = 0; (rc == TWO_LINK_ARM_OK) && (i < TWO_LINK_ARM_NQ); i++) {
        if (q[i] < (real)0) {
            rc = TWO_LINK_ARM_ERR_ARG;
        }
    }
    for (i = 0; (rc == TWO_LINK_ARM_OK) && (i < TWO_LINK_ARM_NYY); i++) {
        real rt = R[((i % NY) * NY) + (i / NY)];
        if ((R[i] < rt) || (R[i] > rt)) {
            rc = TWO_LINK_ARM_ERR_ARG;
        }
    }
    if ((rc == TWO_LINK_ARM_OK) && (two_link_arm_spd(R, NY) == 0)) {
        rc = TWO_LINK_ARM_ERR_SINGULAR;
    }
    /* P0 must be symmetric positive definite */
    if ((rc == TWO_LINK_ARM_OK) && (two_link_arm_cov_ok(P0) == 0)) {
        rc = TWO_LINK_ARM_ERR_ARG;
    }
    /* x0 in the model's domain: else no input predicts out of it (the centre is 0 here) */
    if ((rc == TWO_LINK_ARM_OK) && (two_link_arm_in_domain(x0) == 0)) {
        rc = TWO_LINK_ARM_ERR_ARG;
    }
    if (rc == TWO_LINK_ARM_OK) {
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
        (void)two_link_arm_kern_noise(q, node->Qd);
        recentre(node, node->post);
    }
    return rc;
}

/* A node started mid-run holds the prior of step 0 for a later step, perhaps far from the plant
 * (a restart): a replay through that prior alone corrects it by as much, and the held mean over
 * that correction departs from the Phi the master's difference rule assumes (docs/algorithms.md,
 * node). Its window starts at its first measurement. */
int two_link_arm_node_mid_run(two_link_arm_node* node)
{
    int rc = TWO_LINK_ARM_OK;
    if (node == NULL) {
        rc = TWO_LINK_ARM_ERR_ARG;
    } else if ((node->k != 0u) || (node->updated != 0u)) {
        rc = TWO_LINK_ARM_ERR_SEQUENCE;
    } else {
        node->measured = 0u;
    }
    return rc;
}

/* A failed update puts step k's prior back (see node_update). */
static void put_back_prior(two_link_arm_node* node)
{
    (void)memcpy(node->post, node->pred, sizeof(node->post));
    (void)memset(&node->ring_z[(int)node->slot * NY], 0, sizeof(real) * (size_t)NY);
}

/* While step k is not updated, post equals its prior (pred, whose x also equals its ring
 * slot's) and its z slot is 0: the update computes into them in place, and a failure
 * puts the prior back. A step without a measurement keeps its prior. */
int two_link_arm_node_update(two_link_arm_node* node, const real z[NY], int gamma)
{
    real piv[NY];
    real e[NY];
    real* zk;
    int rc = TWO_LINK_ARM_OK;
    if ((node == NULL) || ((gamma != 0) && (gamma != 1)) || ((gamma == 1) && (z == NULL))) {
        rc = TWO_LINK_ARM_ERR_ARG;
    }
    if ((rc == TWO_LINK_ARM_OK) && (node->updated != 0u)) {
        rc = TWO_LINK_ARM_ERR_SEQUENCE;
    }
    if ((rc == TWO_LINK_ARM_OK) && (gamma == 1)) { /* a non-finite z makes the posterior so */
        zk = &node->ring_z[(int)node->slot * NY];
        centred(node, z, zk);
        innovation(node->pred, zk, e);
        (void)two_link_arm_kern_update(node->pred, e, node->R, node->post, piv);
        if (pivots_ok(piv) == 0) {
            rc = TWO_LINK_ARM_ERR_SINGULAR;
        } else if (finite_state(node->post) == 0) {
            rc = TWO_LINK_ARM_ERR_NONFINITE;
        } else {
            /* a finite posterior */
        }
        if (rc != TWO_LINK_ARM_OK) {
            put_back_prior(node);
        }
    }
    if (rc == TWO_LINK_ARM_OK) {
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
    int rc = TWO_LINK_ARM_OK;
    if (used != 0) {
        innovation(prior, z, e);
        (void)two_link_arm_kern_update(prior, e, R, post, piv);
        if (pivots_ok(piv) == 0) {
            rc = TWO_LINK_ARM_ERR_SINGULAR;
        } else if (finite_state(post) == 0) {
            rc = TWO_LINK_ARM_ERR_NONFINITE;
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
static int prior_P(const two_link_arm_node* node, uint32_t j, real* prior)
{
    real post[NXP];
    real zero[NY];
    uint32_t s = j - (j % TWO_LINK_ARM_NODE_CHECK_EVERY);
    int rc = TWO_LINK_ARM_OK;
    (void)memset(prior, 0, sizeof(real) * (size_t)NX);
    (void)memset(zero, 0, sizeof(zero));
    (void)memcpy(&prior[NX], &node->ring_P[check_of(node, s) * NPP], sizeof(real) * (size_t)NPP);
    while ((rc == TWO_LINK_ARM_OK) && (s != j)) { /* s <= j, modulo 2^32 */
        int used = 0;
        if ((node->ring_flags[hist_of(node, s)] & USED) != 0u) {
            used = 1;
        }
        rc = update_step(prior, zero, used, node->R, post);
        if (rc == TWO_LINK_ARM_OK) {
            /* the covariance alone: the held mean at x = 0 may leave the model's domain */
            (void)two_link_arm_kern_node_predict_P(&post[NX], node->Qd, &prior[NX]);
            if (two_link_arm_finite(&prior[NX], (size_t)NPP) == 0) {
                rc = TWO_LINK_ARM_ERR_NONFINITE;
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
static int replay(two_link_arm_node* node, uint32_t j0, const real* zlate, real* post)
{
    real old_x[TWO_LINK_ARM_NMAX * NX];
    real old_P[TWO_LINK_ARM_NODE_NCHECK_REALS];
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
    while ((rc == TWO_LINK_ARM_OK) && (j != stop)) {
        int slot = slot_of(node, j);
        real* xnext = &node->ring_x[slot_of(node, j + 1u) * NX];
        const real* z = (j == j0) ? zlate : &node->ring_z[slot * NY];
        int used = 1; /* the late step, and the steps the history used */
        if ((j != j0) && ((node->ring_flags[hist_of(node, j)] & USED) == 0u)) {
            used = 0;
        }
        rc = update_step(prior, z, used, node->R, post);
        if ((rc == TWO_LINK_ARM_OK) && (j != node->k)) {
            (void)memcpy(&old_x[written * (uint32_t)NX], xnext, sizeof(real) * (size_t)NX);
            written++;
            rc = predict_step(post, &node->ring_v[slot * NW], node->Qd, node->centre, prior);
            if (rc == TWO_LINK_ARM_OK) {
                (void)memcpy(xnext, prior, sizeof(real) * (size_t)NX);
            }
            if ((rc == TWO_LINK_ARM_OK) && (((j + 1u) % TWO_LINK_ARM_NODE_CHECK_EVERY) == 0u)) {
                real* cp = &node->ring_P[check_of(node, j + 1u) * NPP];
                (void)memcpy(&old_P[checks * NPP], cp, sizeof(real) * (size_t)NPP);
                checks++;
                (void)memcpy(cp, &prior[NX], sizeof(real) * (size_t)NPP);
            }
        }
        j++;
    }
    if (rc != TWO_LINK_ARM_OK) {
        first = j0 - (j0 % TWO_LINK_ARM_NODE_CHECK_EVERY); /* the first checkpoint after j0 */
        first += TWO_LINK_ARM_NODE_CHECK_EVERY;
        for (i = 0u; i < written; i++) {
            (void)memcpy(&node->ring_x[slot_of(node, j0 + 1u + i) * NX], &old_x[i * (uint32_t)NX],
                         sizeof(real) * (size_t)NX);
        }
        for (c = 0; c < checks; c++) {
            (void)memcpy(&node->ring_P[check_of(node, first) * NPP], &old_P[c * NPP],
                         sizeof(real) * (size_t)NPP);
            first += TWO_LINK_ARM_NODE_CHECK_EVERY;
        }
    }
    return rc;
}

int two_link_arm_node_update_delayed(two_link_arm_node* node, const real z_abs[NY], int32_t lag)
{
    real post[NXP];
    real z[NY];
    uint32_t N = 0u;
    int hist = 0;
    int rc = TWO_LINK_ARM_OK;
    if ((node == NULL) || (z_abs == NULL)) {
        rc = TWO_LINK_ARM_ERR_ARG;
    }
    if ((rc == TWO_LINK_ARM_OK) && (node->updated == 0u)) {
        rc = TWO_LINK_ARM_ERR_SEQUENCE;
    }
    if ((rc == TWO_LINK_ARM_OK) && (two_link_arm_finite(z_abs, NY) == 0)) {
        rc = TWO_LINK_ARM_ERR_NONFINITE;
    }
    if ((rc == TWO_LINK_ARM_OK) && ((lag < 1) || (lag > TWO_LINK_ARM_NMAX))) {
        node->health.late_rejected++;
        rc = TWO_LINK_ARM_ERR_LAG;
    }
    /* before step 0, or (started mid-run) before the first measurement, which holds the start-up
     * prior alone */
    if ((rc == TWO_LINK_ARM_OK) && ((node->measured == 0u) || ((uint32_t)lag > node->age))) {
        node->health.late_rejected++;
        rc = TWO_LINK_ARM_ERR_LAG;
    }
    if (rc == TWO_LINK_ARM_OK) {
        centred(node, z_abs, z);
        N = (uint32_t)lag;
        hist = hist_of(node, node->k - N);
        if ((node->ring_flags[hist] & HAS) != 0u) {
            node->health.late_rejected++;
            rc = TWO_LINK_ARM_ERR_DUPLICATE;
        }
    }
    if (rc == TWO_LINK_ARM_OK) {
        rc = replay(node, node->k - N, z, post);
    }
    if (rc == TWO_LINK_ARM_OK) {
        (void)memcpy(&node->ring_z[slot_of(node, node->k - N) * NY], z, sizeof(real) * (size_t)NY);
        node->ring_flags[hist] = (uint8_t)(HAS | USED);
    }
    if (rc == TWO_LINK_ARM_OK) {
        (void)memcpy(node->post, post, sizeof(post));
        node->health.late_applied++;
    }
    return rc;
}

int two_link_arm_node_predict(two_link_arm_node* node, const real input[NW])
{
    const real* v = input;
    real next[NXP];
    int slot;
    uint32_t hist;
    uint32_t check;
    int rc = TWO_LINK_ARM_OK;
    if ((node == NULL) || (v == NULL)) {
        rc = TWO_LINK_ARM_ERR_ARG;
    }
    if ((rc == TWO_LINK_ARM_OK) && (node->updated == 0u)) {
        rc = TWO_LINK_ARM_ERR_SEQUENCE;
    }
    if (rc == TWO_LINK_ARM_OK) { /* a non-finite v makes the prediction so */
        rc = predict_step(node->post, v, node->Qd, node->centre, next);
    }
    if (rc == TWO_LINK_ARM_OK) {
        slot = (int)node->slot;
        (void)memcpy(&node->ring_v[slot * NW], v, sizeof(real) * (size_t)NW);
        node->k++;
        slot = (slot == TWO_LINK_ARM_NMAX) ? 0 : (slot + 1);
        node->slot = (uint16_t)slot;
        hist = (uint32_t)node->hist + 1u;
        node->hist = (uint16_t)((hist == TWO_LINK_ARM_NODE_NHIST) ? 0u : hist);
        (void)memcpy(&node->ring_x[slot * NX], next, sizeof(real) * (size_t)NX);
        if (node->age < TWO_LINK_ARM_NODE_NHIST) {
            node->age++;
        }
        if ((node->k % TWO_LINK_ARM_NODE_CHECK_EVERY) == 0u) {
            check = (uint32_t)node->check + 1u;
            node->check = (uint16_t)((check == TWO_LINK_ARM_NODE_NCHECK) ? 0u : check);
            (void)memcpy(&node->ring_P[(int)node->check * NPP], &next[NX],
                         sizeof(real) * (size_t)NPP);
        }
        (void)memset(&node->ring_z[slot * NY], 0, sizeof(real) * (size_t)NY);
        (void)memcpy(node->post, next, sizeof(next));
        (void)memcpy(node->pred, next, sizeof(next));
        node->updated = 0;
        recentre(node, next);
    }
    return rc;
}

int two_link_arm_node_estimate(const two_link_arm_node* node, real x[NX], real P[NXX])
{
    int rc = TWO_LINK_ARM_OK;
    if (node == NULL) {
        rc = TWO_LINK_ARM_ERR_ARG;
    } else {
        if (x != NULL) {
            two_link_arm_move_origin(node->post, node->centre, NULL, x);
        }
        if (P != NULL) {
            unpack(&node->post[NX], P);
        }
    }
    return rc;
}

int two_link_arm_node_information(const two_link_arm_node* node, real Y[NXX], real y[NX])
{
    real Yl[NXX];
    real yl[NX];
    real piv[NX];
    real origin[NX];
    real x[NX];
    real P[NXX];
    int rc = TWO_LINK_ARM_OK;
    if (node == NULL) {
        rc = TWO_LINK_ARM_ERR_ARG;
    }
    if (rc == TWO_LINK_ARM_OK) {
        (void)memset(origin, 0, sizeof(origin));
        two_link_arm_move_origin(node->post, node->centre, NULL, x);
        unpack(&node->post[NX], P);
        (void)two_link_arm_kern_info(x, P, origin, Yl, yl, piv);
        if (two_link_arm_positive(piv, NX) == 0) {
            rc = TWO_LINK_ARM_ERR_SINGULAR;
        }
    }
    if ((rc == TWO_LINK_ARM_OK) &&
        ((two_link_arm_finite(Yl, NXX) == 0) || (two_link_arm_finite(yl, NX) == 0))) {
        rc = TWO_LINK_ARM_ERR_NONFINITE;
    }
    if (rc == TWO_LINK_ARM_OK) {
        if (Y != NULL) {
            (void)memcpy(Y, Yl, sizeof(Yl));
        }
        if (y != NULL) {
            (void)memcpy(y, yl, sizeof(yl));
        }
    }
    return rc;
}

int two_link_arm_node_packet(const two_link_arm_node* node, two_link_arm_packet* packet)
{
    int rc = TWO_LINK_ARM_OK;
    if ((node == NULL) || (packet == NULL)) {
        rc = TWO_LINK_ARM_ERR_ARG;
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

int two_link_arm_node_health(const two_link_arm_node* node, two_link_arm_health* health)
{
    int rc = TWO_LINK_ARM_OK;
    if ((node == NULL) || (health == NULL)) {
        rc = TWO_LINK_ARM_ERR_ARG;
    } else {
        *health = node->health;
    }
    return rc;
}
