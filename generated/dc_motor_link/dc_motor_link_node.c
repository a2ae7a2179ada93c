/* DO NOT EDIT: dc_motor_link module, generated from template node_replay.c.j2 by dfeif-codegen
 * 0.1.0; regenerate with `codegen build dc_motor_link`. */
/* One camera node: the local derivative-free Kalman filter with packet drops and late
 * measurements (replay), following docs/algorithms.md. Every public function validates and
 * computes into locals first and writes the node only once nothing can fail. */
#include <string.h>
#include "dc_motor_link_internal.h"

#define NX DC_MOTOR_LINK_NX
#define NY DC_MOTOR_LINK_NY
#define NXX (DC_MOTOR_LINK_NX * DC_MOTOR_LINK_NX)
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

static int slot_of(uint32_t step)
{
    uint32_t slot = step % ((uint32_t)DC_MOTOR_LINK_NMAX + 1u);
    return (int)slot;
}

/* Measurement relative to the node's centre. */
static void centred(const dc_motor_link_node* node, const real* z, real* zc)
{
    int j;
    for (j = 0; j < NY; j++) {
        zc[j] = z[j] - node->centre[j];
    }
}

/* Move each output's centre by whole steps to within half a step of the estimate, and every
 * stored value with it. Moving the centre leaves A x + B v unchanged: it only touches the chain
 * heads, and A maps a head-only vector to itself. */
static void recentre(dc_motor_link_node* node)
{
    int j, s;
    for (j = 0; j < NY; j++) {
        real shift = dc_motor_link_centre_shift(node->x[dc_motor_link_heads[j]]);
        if (shift == (real)0) {
            continue;
        }
        node->centre[j] += shift;
        node->x[dc_motor_link_heads[j]] -= shift;
        node->x_pred[dc_motor_link_heads[j]] -= shift;
        for (s = 0; s < SLOTS; s++) {
            node->ring_x[s * NX + (int)dc_motor_link_heads[j]] -= shift;
            node->ring_z[s * NY + j] -= shift;
        }
    }
}

/* Filter update of one step from a prior; 0 or an error code. */
static int update_step(const real* xm, const real* Pm, const real* z, real gamma, const real* R,
                       real* x, real* P)
{
    real piv[NY];
    real w[DC_MOTOR_LINK_KERN_UPDATE_SZ_W];
    (void)dc_motor_link_kern_update(xm, Pm, z, &gamma, R, x, P, piv, w);
    if (gamma > (real)0 && !dc_motor_link_positive(piv, NY)) {
        return DC_MOTOR_LINK_ERR_SINGULAR;
    }
    if (!dc_motor_link_finite(x, NX) || !dc_motor_link_finite(P, NXX)) {
        return DC_MOTOR_LINK_ERR_NONFINITE;
    }
    return DC_MOTOR_LINK_OK;
}

/* Prediction x1 = A x + B v, P1 = A P A' + Q; 0 or an error code. */
static int predict_step(const real* x, const real* P, const real* v, const real* q, real* x1,
                        real* P1)
{
    real w[DC_MOTOR_LINK_KERN_PREDICT_SZ_W];
    (void)dc_motor_link_kern_predict(x, P, v, q, x1, P1, w);
    if (!dc_motor_link_finite(x1, NX) || !dc_motor_link_finite(P1, NXX)) {
        return DC_MOTOR_LINK_ERR_NONFINITE;
    }
    return DC_MOTOR_LINK_OK;
}

int dc_motor_link_cov_ok(const real* A)
{
    real L[NXX], d[NX];
    return dc_motor_link_spd_in(A, NX, L, d);
}

int dc_motor_link_node_init(dc_motor_link_node* node, const real x0[NX], const real P0[NXX],
                            const real R[NY * NY], const real q[NY])
{
    int i;
    if (!node || !x0 || !P0 || !R || !q) {
        return DC_MOTOR_LINK_ERR_ARG;
    }
    if (!dc_motor_link_finite(x0, NX) || !dc_motor_link_finite(P0, NXX) ||
        !dc_motor_link_finite(R, NY * NY) || !dc_motor_link_finite(q, NY)) {
        return DC_MOTOR_LINK_ERR_NONFINITE;
    }
    for (i = 0; i < NY; i++) {
        if (q[i] < (real)0) {
            return DC_MOTOR_LINK_ERR_ARG;
        }
    }
    for (i = 0; i < NY * NY; i++) {
        if (R[i] < R[(i % NY) * NY + i / NY] || R[i] > R[(i % NY) * NY + i / NY]) {
            return DC_MOTOR_LINK_ERR_ARG;
        }
    }
    if (!dc_motor_link_spd(R, NY)) {
        return DC_MOTOR_LINK_ERR_SINGULAR;
    }
    if (dc_motor_link_cov_ok(P0) == 0) { /* P0 must be symmetric positive definite */
        return DC_MOTOR_LINK_ERR_ARG;
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
    return DC_MOTOR_LINK_OK;
}

int dc_motor_link_node_update(dc_motor_link_node* node, const real z[NY], int gamma)
{
    real zz[NY], x[NX], P[NXX];
    int slot;
    int rc;
    if (!node || (gamma != 0 && gamma != 1) || (gamma == 1 && !z)) {
        return DC_MOTOR_LINK_ERR_ARG;
    }
    if (node->updated != 0u) {
        return DC_MOTOR_LINK_ERR_SEQUENCE;
    }
    (void)memset(zz, 0, sizeof(zz));
    if (gamma == 1) {
        if (!dc_motor_link_finite(z, NY)) {
            return DC_MOTOR_LINK_ERR_NONFINITE;
        }
        centred(node, z, zz);
    }
    slot = slot_of(node->k);
    rc = update_step(&node->ring_x[slot * NX], &node->ring_P[slot * NXX], zz, (real)gamma, node->R,
                     x, P);
    if (rc != DC_MOTOR_LINK_OK) {
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
    return DC_MOTOR_LINK_OK;
}

/* Re-run steps j0..k in one pass: the update of each step from its prior (slot j0 with the late
 * z), then the prediction into the next slot, written in place; returns the posterior of step k.
 * On a failure the slots are put back as they were: the priors' x from a copy, the priors' P by
 * recomputing the old history from slot j0 (the P recursion reads neither x nor z, so it gives
 * the old values bit for bit, and it succeeded before). */
static int replay(dc_motor_link_node* node, uint32_t j0, const real* zlate, real* x, real* P)
{
    real old_x[DC_MOTOR_LINK_NMAX * NX];
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
        if (rc == DC_MOTOR_LINK_OK && j != node->k) {
            (void)memcpy(&old_x[(int)written * NX], &node->ring_x[next * NX],
                         sizeof(real) * (size_t)NX);
            written++;
            rc = predict_step(x, P, &node->ring_v[slot * NY], node->q, &node->ring_x[next * NX],
                              &node->ring_P[next * NXX]);
        }
        j++;
    } while (rc == DC_MOTOR_LINK_OK && j <= node->k);
    for (i = 0u; rc != DC_MOTOR_LINK_OK && i < written; i++) {
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

int dc_motor_link_node_update_delayed(dc_motor_link_node* node, const real z_abs[NY], int32_t lag)
{
    real x[NX], P[NXX], z[NY];
    uint32_t N;
    int slot;
    int rc;
    if (!node || !z_abs) {
        return DC_MOTOR_LINK_ERR_ARG;
    }
    if (!node->updated) {
        return DC_MOTOR_LINK_ERR_SEQUENCE;
    }
    if (!dc_motor_link_finite(z_abs, NY)) {
        return DC_MOTOR_LINK_ERR_NONFINITE;
    }
    centred(node, z_abs, z);
    if (lag < 1 || lag > DC_MOTOR_LINK_NMAX || (uint32_t)lag > node->k) {
        node->health.late_rejected++;
        return DC_MOTOR_LINK_ERR_LAG;
    }
    N = (uint32_t)lag;
    slot = slot_of(node->k - N);
    if ((node->ring_flags[slot] & HAS) != 0u) {
        node->health.late_rejected++;
        return DC_MOTOR_LINK_ERR_DUPLICATE;
    }
    rc = replay(node, node->k - N, z, x, P);
    if (rc != DC_MOTOR_LINK_OK) {
        return rc;
    }
    (void)memcpy(&node->ring_z[slot * NY], z, sizeof(real) * (size_t)NY);
    node->ring_flags[slot] = (uint8_t)(HAS | USED);
    (void)memcpy(node->x, x, sizeof(x));
    (void)memcpy(node->P, P, sizeof(P));
    node->health.late_applied++;
    return DC_MOTOR_LINK_OK;
}

int dc_motor_link_node_predict(dc_motor_link_node* node, const real v[NY])
{
    real x1[NX], P1[NXX];
    int slot;
    int rc;
    if (!node || !v) {
        return DC_MOTOR_LINK_ERR_ARG;
    }
    if (!node->updated) {
        return DC_MOTOR_LINK_ERR_SEQUENCE;
    }
    if (!dc_motor_link_finite(v, NY)) {
        return DC_MOTOR_LINK_ERR_NONFINITE;
    }
    rc = predict_step(node->x, node->P, v, node->q, x1, P1);
    if (rc != DC_MOTOR_LINK_OK) {
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
    return DC_MOTOR_LINK_OK;
}

int dc_motor_link_node_estimate(const dc_motor_link_node* node, real x[NX], real P[NXX])
{
    if (!node) {
        return DC_MOTOR_LINK_ERR_ARG;
    }
    if (x != NULL) {
        dc_motor_link_move_origin(node->x, node->centre, NULL, x);
    }
    if (P != NULL) {
        (void)memcpy(P, node->P, sizeof(node->P));
    }
    return DC_MOTOR_LINK_OK;
}

int dc_motor_link_node_information(const dc_motor_link_node* node, real Y[NXX], real y[NX])
{
    real Yl[NXX], yl[NX], piv[NX], origin[NX], x[NX];
    real w[DC_MOTOR_LINK_KERN_INFO_SZ_W];
    if (!node) {
        return DC_MOTOR_LINK_ERR_ARG;
    }
    (void)memset(origin, 0, sizeof(origin));
    dc_motor_link_move_origin(node->x, node->centre, NULL, x);
    (void)dc_motor_link_kern_info(x, node->P, origin, Yl, yl, piv, w);
    if (!dc_motor_link_positive(piv, NX)) {
        return DC_MOTOR_LINK_ERR_SINGULAR;
    }
    if (!dc_motor_link_finite(Yl, NXX) || !dc_motor_link_finite(yl, NX)) {
        return DC_MOTOR_LINK_ERR_NONFINITE;
    }
    if (Y != NULL) {
        (void)memcpy(Y, Yl, sizeof(Yl));
    }
    if (y != NULL) {
        (void)memcpy(y, yl, sizeof(yl));
    }
    return DC_MOTOR_LINK_OK;
}

int dc_motor_link_node_packet(const dc_motor_link_node* node, dc_motor_link_packet* packet)
{
    if (!node || !packet) {
        return DC_MOTOR_LINK_ERR_ARG;
    }
    packet->step = node->k;
    (void)memcpy(packet->centre, node->centre, sizeof(packet->centre));
    (void)memcpy(packet->x, node->x, sizeof(packet->x));
    (void)memcpy(packet->P, node->P, sizeof(packet->P));
    (void)memcpy(packet->x_pred, node->x_pred, sizeof(packet->x_pred));
    (void)memcpy(packet->P_pred, node->P_pred, sizeof(packet->P_pred));
    return DC_MOTOR_LINK_OK;
}

int dc_motor_link_node_health(const dc_motor_link_node* node, dc_motor_link_health* health)
{
    if (!node || !health) {
        return DC_MOTOR_LINK_ERR_ARG;
    }
    *health = node->health;
    return DC_MOTOR_LINK_OK;
}
