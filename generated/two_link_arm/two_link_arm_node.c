/* DO NOT EDIT: two_link_arm module, generated from template node_replay.c.j2 by dfeif-codegen
 * 0.1.0; regenerate with `codegen build two_link_arm`. */
/* One camera node: the local derivative-free Kalman filter with packet drops and late
 * measurements (replay), following docs/algorithms.md. Every public function validates and
 * computes into locals first and writes the node only once nothing can fail. */
#include <string.h>
#include "two_link_arm_internal.h"

#define NX TWO_LINK_ARM_NX
#define NY TWO_LINK_ARM_NY
#define NXX (TWO_LINK_ARM_NX * TWO_LINK_ARM_NX)
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

static int slot_of(uint32_t step)
{
    uint32_t slot = step % ((uint32_t)TWO_LINK_ARM_NMAX + 1u);
    return (int)slot;
}

/* Measurement relative to the node's centre. */
static void centred(const two_link_arm_node* node, const real* z, real* zc)
{
    int j;
    for (j = 0; j < NY; j++) {
        zc[j] = z[j] - node->centre[j];
    }
}

/* Move each output's centre by whole steps to within half a step of the estimate, and every
 * stored value with it. Moving the centre leaves A x + B v unchanged: it only touches the chain
 * heads, and A maps a head-only vector to itself. */
static void recentre(two_link_arm_node* node)
{
    int j, s;
    for (j = 0; j < NY; j++) {
        real shift = two_link_arm_centre_shift(node->x[two_link_arm_heads[j]]);
        if (shift == (real)0) {
            continue;
        }
        node->centre[j] += shift;
        node->x[two_link_arm_heads[j]] -= shift;
        node->x_pred[two_link_arm_heads[j]] -= shift;
        for (s = 0; s < SLOTS; s++) {
            node->ring_x[s * NX + (int)two_link_arm_heads[j]] -= shift;
            node->ring_z[s * NY + j] -= shift;
        }
    }
}

/* Filter update of one step from a prior; 0 or an error code. */
static int update_step(const real* xm, const real* Pm, const real* z, real gamma, const real* R,
                       real* x, real* P)
{
    real piv[NY];
    real w[TWO_LINK_ARM_KERN_UPDATE_SZ_W];
    (void)two_link_arm_kern_update(xm, Pm, z, &gamma, R, x, P, piv, w);
    if (gamma > (real)0 && !two_link_arm_positive(piv, NY)) {
        return TWO_LINK_ARM_ERR_SINGULAR;
    }
    if (!two_link_arm_finite(x, NX) || !two_link_arm_finite(P, NXX)) {
        return TWO_LINK_ARM_ERR_NONFINITE;
    }
    return TWO_LINK_ARM_OK;
}

/* Prediction x1 = A x + B v, P1 = A P A' + Q; 0 or an error code. */
static int predict_step(const real* x, const real* P, const real* v, const real* q, real* x1,
                        real* P1)
{
    real w[TWO_LINK_ARM_KERN_PREDICT_SZ_W];
    (void)two_link_arm_kern_predict(x, P, v, q, x1, P1, w);
    if (!two_link_arm_finite(x1, NX) || !two_link_arm_finite(P1, NXX)) {
        return TWO_LINK_ARM_ERR_NONFINITE;
    }
    return TWO_LINK_ARM_OK;
}

int two_link_arm_cov_ok(const real* A)
{
    real L[NXX], d[NX];
    return two_link_arm_spd_in(A, NX, L, d);
}

int two_link_arm_node_init(two_link_arm_node* node, const real x0[NX], const real P0[NXX],
                           const real R[NY * NY], const real q[NY])
{
    int i;
    if (!node || !x0 || !P0 || !R || !q) {
        return TWO_LINK_ARM_ERR_ARG;
    }
    if (!two_link_arm_finite(x0, NX) || !two_link_arm_finite(P0, NXX) ||
        !two_link_arm_finite(R, NY * NY) || !two_link_arm_finite(q, NY)) {
        return TWO_LINK_ARM_ERR_NONFINITE;
    }
    for (i = 0; i < NY; i++) {
        if (q[i] < (real)0) {
            return TWO_LINK_ARM_ERR_ARG;
        }
    }
    for (i = 0; i < NY * NY; i++) {
        if (R[i] < R[(i % NY) * NY + i / NY] || R[i] > R[(i % NY) * NY + i / NY]) {
            return TWO_LINK_ARM_ERR_ARG;
        }
    }
    if (!two_link_arm_spd(R, NY)) {
        return TWO_LINK_ARM_ERR_SINGULAR;
    }
    if (two_link_arm_cov_ok(P0) == 0) { /* P0 must be symmetric positive definite */
        return TWO_LINK_ARM_ERR_ARG;
    }
    (void)memset(node, 0, sizeof(*node));
    (void)memcpy(node->x, x0, sizeof(node->x));
    (void)memcpy(node->P, P0, sizeof(node->P));
    (void)memcpy(node->x_pred, x0, sizeof(node->x_pred));
    (void)memcpy(node->P_pred, P0, sizeof(node->P_pred));
    (void)memcpy(node->ring_x, x0, sizeof(node->x));
    (void)memcpy(node->ring_P, P0, sizeof(node->P));
    (void)memcpy(node->R, R, sizeof(node->R));
    (void)memcpy(node->q, q, sizeof(node->q));
    recentre(node);
    return TWO_LINK_ARM_OK;
}

int two_link_arm_node_update(two_link_arm_node* node, const real z[NY], int gamma)
{
    real zz[NY], x[NX], P[NXX];
    int slot;
    int rc;
    if (!node || (gamma != 0 && gamma != 1) || (gamma == 1 && !z)) {
        return TWO_LINK_ARM_ERR_ARG;
    }
    if (node->updated != 0u) {
        return TWO_LINK_ARM_ERR_SEQUENCE;
    }
    (void)memset(zz, 0, sizeof(zz));
    if (gamma == 1) {
        if (!two_link_arm_finite(z, NY)) {
            return TWO_LINK_ARM_ERR_NONFINITE;
        }
        centred(node, z, zz);
    }
    slot = slot_of(node->k);
    rc = update_step(&node->ring_x[slot * NX], &node->ring_P[slot * NXX], zz, (real)gamma, node->R,
                     x, P);
    if (rc != TWO_LINK_ARM_OK) {
        return rc;
    }
    (void)memcpy(node->x, x, sizeof(x));
    (void)memcpy(node->P, P, sizeof(P));
    (void)memcpy(&node->ring_z[slot * NY], zz, sizeof(zz));
    node->ring_flags[slot] = (uint8_t)(gamma == 1 ? (HAS | USED) : 0u);
    node->updated = 1;
    if (gamma == 1) {
        node->health.updates++;
    } else {
        node->health.drops++;
    }
    return TWO_LINK_ARM_OK;
}

/* Re-run steps j0..k in one pass: the update of each step from its prior (slot j0 with the late
 * z), then the prediction into the next slot, written in place; returns the posterior of step k.
 * On a failure the slots are put back as they were: the priors' x from a copy, the priors' P by
 * recomputing the old history from slot j0 (the P recursion reads neither x nor z, so it gives
 * the old values bit for bit, and it succeeded before). */
static int replay(two_link_arm_node* node, uint32_t j0, const real* zlate, real* x, real* P)
{
    real old_x[TWO_LINK_ARM_NMAX * NX];
    real xd[NX], Pd[NXX], xe[NX];
    uint32_t j = j0;
    uint32_t written = 0u; /* priors rewritten so far: slots j0 + 1 .. j0 + written */
    uint32_t i;
    int rc;
    do {
        int slot = slot_of(j);
        int next = slot_of(j + 1u);
        const real* z = (j == j0) ? zlate : &node->ring_z[slot * NY];
        real gamma = (j == j0 || (node->ring_flags[slot] & USED) != 0u) ? (real)1 : (real)0;
        rc = update_step(&node->ring_x[slot * NX], &node->ring_P[slot * NXX], z, gamma, node->R, x,
                         P);
        if (rc == TWO_LINK_ARM_OK && j != node->k) {
            (void)memcpy(&old_x[(int)written * NX], &node->ring_x[next * NX],
                         sizeof(real) * (size_t)NX);
            written++;
            rc = predict_step(x, P, &node->ring_v[slot * NY], node->q, &node->ring_x[next * NX],
                              &node->ring_P[next * NXX]);
        }
        j++;
    } while (rc == TWO_LINK_ARM_OK && j <= node->k);
    for (i = 0u; rc != TWO_LINK_ARM_OK && i < written; i++) {
        int s = slot_of(j0 + i);
        int after = slot_of(j0 + i + 1u);
        real g = ((node->ring_flags[s] & USED) != 0u) ? (real)1 : (real)0;
        (void)memcpy(&node->ring_x[after * NX], &old_x[(int)i * NX], sizeof(real) * (size_t)NX);
        (void)update_step(&node->ring_x[s * NX], &node->ring_P[s * NXX], &node->ring_z[s * NY], g,
                          node->R, xd, Pd);
        (void)predict_step(xd, Pd, &node->ring_v[s * NY], node->q, xe, &node->ring_P[after * NXX]);
    }
    return rc;
}

int two_link_arm_node_update_delayed(two_link_arm_node* node, const real z_abs[NY], int32_t lag)
{
    real x[NX], P[NXX], z[NY];
    uint32_t N;
    int slot;
    int rc;
    if (!node || !z_abs) {
        return TWO_LINK_ARM_ERR_ARG;
    }
    if (!node->updated) {
        return TWO_LINK_ARM_ERR_SEQUENCE;
    }
    if (!two_link_arm_finite(z_abs, NY)) {
        return TWO_LINK_ARM_ERR_NONFINITE;
    }
    centred(node, z_abs, z);
    if (lag < 1 || lag > TWO_LINK_ARM_NMAX || (uint32_t)lag > node->k) {
        node->health.late_rejected++;
        return TWO_LINK_ARM_ERR_LAG;
    }
    N = (uint32_t)lag;
    slot = slot_of(node->k - N);
    if ((node->ring_flags[slot] & HAS) != 0u) {
        node->health.late_rejected++;
        return TWO_LINK_ARM_ERR_DUPLICATE;
    }
    rc = replay(node, node->k - N, z, x, P);
    if (rc != TWO_LINK_ARM_OK) {
        return rc;
    }
    (void)memcpy(&node->ring_z[slot * NY], z, sizeof(real) * (size_t)NY);
    node->ring_flags[slot] = (uint8_t)(HAS | USED);
    (void)memcpy(node->x, x, sizeof(x));
    (void)memcpy(node->P, P, sizeof(P));
    node->health.late_applied++;
    return TWO_LINK_ARM_OK;
}

int two_link_arm_node_predict(two_link_arm_node* node, const real v[NY])
{
    real x1[NX], P1[NXX];
    int slot;
    int rc;
    if (!node || !v) {
        return TWO_LINK_ARM_ERR_ARG;
    }
    if (!node->updated) {
        return TWO_LINK_ARM_ERR_SEQUENCE;
    }
    if (!two_link_arm_finite(v, NY)) {
        return TWO_LINK_ARM_ERR_NONFINITE;
    }
    rc = predict_step(node->x, node->P, v, node->q, x1, P1);
    if (rc != TWO_LINK_ARM_OK) {
        return rc;
    }
    (void)memcpy(&node->ring_v[slot_of(node->k) * NY], v, sizeof(real) * (size_t)NY);
    node->k++;
    slot = slot_of(node->k);
    (void)memcpy(&node->ring_x[slot * NX], x1, sizeof(x1));
    (void)memcpy(&node->ring_P[slot * NXX], P1, sizeof(P1));
    (void)memset(&node->ring_z[slot * NY], 0, sizeof(real) * (size_t)NY);
    node->ring_flags[slot] = 0;
    (void)memcpy(node->x, x1, sizeof(x1));
    (void)memcpy(node->P, P1, sizeof(P1));
    (void)memcpy(node->x_pred, x1, sizeof(x1));
    (void)memcpy(node->P_pred, P1, sizeof(P1));
    node->updated = 0;
    recentre(node);
    return TWO_LINK_ARM_OK;
}

int two_link_arm_node_estimate(const two_link_arm_node* node, real x[NX], real P[NXX])
{
    if (!node) {
        return TWO_LINK_ARM_ERR_ARG;
    }
    if (x != NULL) {
        two_link_arm_move_origin(node->x, node->centre, NULL, x);
    }
    if (P != NULL) {
        (void)memcpy(P, node->P, sizeof(node->P));
    }
    return TWO_LINK_ARM_OK;
}

int two_link_arm_node_information(const two_link_arm_node* node, real Y[NXX], real y[NX])
{
    real Yl[NXX], yl[NX], piv[NX], origin[NX], x[NX];
    real w[TWO_LINK_ARM_KERN_INFO_SZ_W];
    if (!node) {
        return TWO_LINK_ARM_ERR_ARG;
    }
    (void)memset(origin, 0, sizeof(origin));
    two_link_arm_move_origin(node->x, node->centre, NULL, x);
    (void)two_link_arm_kern_info(x, node->P, origin, Yl, yl, piv, w);
    if (!two_link_arm_positive(piv, NX)) {
        return TWO_LINK_ARM_ERR_SINGULAR;
    }
    if (!two_link_arm_finite(Yl, NXX) || !two_link_arm_finite(yl, NX)) {
        return TWO_LINK_ARM_ERR_NONFINITE;
    }
    if (Y != NULL) {
        (void)memcpy(Y, Yl, sizeof(Yl));
    }
    if (y != NULL) {
        (void)memcpy(y, yl, sizeof(yl));
    }
    return TWO_LINK_ARM_OK;
}

int two_link_arm_node_packet(const two_link_arm_node* node, two_link_arm_packet* packet)
{
    if (!node || !packet) {
        return TWO_LINK_ARM_ERR_ARG;
    }
    packet->step = node->k;
    (void)memcpy(packet->centre, node->centre, sizeof(packet->centre));
    (void)memcpy(packet->x, node->x, sizeof(packet->x));
    (void)memcpy(packet->P, node->P, sizeof(packet->P));
    (void)memcpy(packet->x_pred, node->x_pred, sizeof(packet->x_pred));
    (void)memcpy(packet->P_pred, node->P_pred, sizeof(packet->P_pred));
    return TWO_LINK_ARM_OK;
}

int two_link_arm_node_health(const two_link_arm_node* node, two_link_arm_health* health)
{
    if (!node || !health) {
        return TWO_LINK_ARM_ERR_ARG;
    }
    *health = node->health;
    return TWO_LINK_ARM_OK;
}
