/* DO NOT EDIT: dc_motor_link module, generated from template example_main.c.j2 by dfeif-codegen
 * 0.1.0; regenerate with `codegen build dc_motor_link`. */
/* Host demo (the only file that uses stdio): DC_MOTOR_LINK_NNODES camera nodes and the master
 * track a sinusoidal reference for 300 steps. The plant is simulated in canonical coordinates
 * with u held, by the filters' own mean map; node 0 loses every 7th measurement and node 1
 * (if any) receives every 5th one 3 steps late.
 * Prints a few steps and the health counters; exits 1 if the fused tracking error is
 * implausible. Build: cc -std=c99 -I. *.c -lm */
#include <stdio.h>
#include <math.h>
#include <string.h>
#include "dc_motor_link.h"
#include "dc_motor_link_kernels.h"

#define NX DC_MOTOR_LINK_NX
#define NY DC_MOTOR_LINK_NY
#define STEPS 300
#define LATE 3 /* at most DC_MOTOR_LINK_NMAX: node_update_delayed refuses older frames */

typedef dc_motor_link_real real;
#define SIN sin
#define SQRT sqrt
#define LOG log
#define COS cos

static const int degree[NY] = DC_MOTOR_LINK_CHAIN_DEGREES;
static const int offset[NY] = DC_MOTOR_LINK_CHAIN_OFFSETS;

/* Deterministic normal noise (LCG + Box-Muller), so runs are reproducible. */
static uint32_t rng_state = 12345u;
static real uniform01(void)
{
    rng_state = rng_state * 1664525u + 1013904223u;
    return ((real)(rng_state >> 8) + 0.5) / 16777216.0;
}
static real normal(void)
{
    real a = uniform01(), b = uniform01();
    return SQRT(-2.0 * LOG(a)) * COS(6.283185307179586 * b);
}

/* One step of the canonical plant with u held over Ts: the filters' own mean map (the held
 * predictor's kernel; its covariance output is not used), so the demo shows the filter and not
 * a model error. */
static void plant(real zeta[NX], const real u[DC_MOTOR_LINK_NW])
{
    real P[NX * NX], P1[NX * NX], x1[NX], Q[DC_MOTOR_LINK_NPP], c[NY];
    memset(P, 0, sizeof(P));
    memset(Q, 0, sizeof(Q));
    memset(c, 0, sizeof(c));
    (void)dc_motor_link_kern_predict(zeta, P, u, Q, c, x1, P1);
    memcpy(zeta, x1, sizeof(x1));
}

/* Where plant and filters start: the model's nominal state in canonical coordinates (the
 * disturbance states, if any, at 0). */
static const real start[NX] = {
    0.0, /* theta_0 */
    0.0, /* theta_1 */
    0.0 /* theta_2 */
};

/* Reference flags: chain j moves as from the start with its top derivative 0 (a polynomial in
 * t), plus 0.3 sin(0.5 t + j), and their derivatives. */
static void reference(real t, real flags[DC_MOTOR_LINK_NFLAGS])
{
    int j, i, l;
    for (j = 0; j < NY; j++) {
        real amp = 0.3;
        for (i = 0; i <= degree[j]; i++) {
            real phase = 0.5 * t + (real)j + (real)i * 1.5707963267948966;
            real drift = 0, term = 1;
            for (l = i; l < degree[j]; l++) {
                drift += term * start[offset[j] + l];
                term = term * t / (real)(l - i + 1);
            }
            flags[offset[j] + j + i] = drift + amp * SIN(phase);
            amp = amp * 0.5;
        }
    }
}

int main(void)
{
    static dc_motor_link_node nodes[DC_MOTOR_LINK_NNODES];
    static dc_motor_link_packet packets[DC_MOTOR_LINK_NNODES];
    static dc_motor_link_master master;
    uint8_t present[DC_MOTOR_LINK_NNODES];
    real zeta[NX], x0[NX], P0[NX * NX], R[NY * NY], q[DC_MOTOR_LINK_NQ], lambda[NY];
    real gains[DC_MOTOR_LINK_NZ];
    real flags[DC_MOTOR_LINK_NFLAGS], x[NX], P[NX * NX], u[NY], v[NY], z[NY];
    real w[DC_MOTOR_LINK_NW]; /* the broadcast input */
    real late[LATE + 1][NY];
    const real* params = dc_motor_link_params_default;
    real sq_err = 0, trace;
    int i, j, k, rc = 0;
    uint32_t saturated = 0;

    memcpy(zeta, start, sizeof(zeta));
    memcpy(x0, start, sizeof(x0));
    memset(P0, 0, sizeof(P0));
    memset(R, 0, sizeof(R));
    for (i = 0; i < NX; i++) {
        P0[i * NX + i] = 0.01;
    }
    for (j = 0; j < NY; j++) {
        R[j * NY + j] = 1e-06;
        q[j] = 1.0;
        lambda[j] = 8.0;
    }
    rc |= dc_motor_link_gains(lambda, gains);
    for (i = 0; i < DC_MOTOR_LINK_NNODES; i++) {
        rc |= dc_motor_link_node_init(&nodes[i], x0, P0, R, q);
    }
    rc |= dc_motor_link_master_init(&master, x0, P0, q);
    if (rc != DC_MOTOR_LINK_OK) {
        printf("init failed\n");
        return 1;
    }
    printf("dc_motor_link: %d nodes, NMAX %d, replay, difference fusion, double\n",
           DC_MOTOR_LINK_NNODES, DC_MOTOR_LINK_NMAX);
    printf("%5s %12s %12s %12s %12s\n", "step", "y1 true", "y1 fused", "tr P", "u1");
    for (k = 0; k < STEPS; k++) {
        for (i = 0; i < DC_MOTOR_LINK_NNODES; i++) {
            for (j = 0; j < NY; j++) {
                z[j] = zeta[offset[j]] + 0.001 * normal();
            }
            if (i == 0 && k % 7 == 3) {
                rc |= dc_motor_link_node_update(&nodes[i], NULL, 0);
            } else if (i == 1 && k % 5 == 0) {
                memcpy(late[k % (LATE + 1)], z, sizeof(z));
                rc |= dc_motor_link_node_update(&nodes[i], NULL, 0);
            } else {
                rc |= dc_motor_link_node_update(&nodes[i], z, 1);
            }
            if (i == 1 && k >= LATE && (k - LATE) % 5 == 0) {
                rc |= dc_motor_link_node_update_delayed(&nodes[i], late[(k - LATE) % (LATE + 1)],
                                                        LATE);
            }
            rc |= dc_motor_link_node_packet(&nodes[i], &packets[i]);
            present[i] = 1;
        }
        rc |= dc_motor_link_master_fuse(&master, packets, present);
        rc |= dc_motor_link_master_estimate(&master, x, P);
        reference((real)k * DC_MOTOR_LINK_TS, flags);
        rc |= dc_motor_link_control(x, flags, gains, params, u, v, &saturated);
        if (rc != DC_MOTOR_LINK_OK) {
            printf("error at step %d\n", k);
            return 1;
        }
        trace = 0;
        for (i = 0; i < NX; i++) {
            trace += P[i * NX + i];
        }
        if (k % 50 == 0 || k == STEPS - 1) {
            printf("%5d %12.6f %12.6f %12.3e %12.4f\n", k, (double)zeta[0], (double)x[0],
                   (double)trace, (double)u[0]);
        }
        sq_err += (x[0] - zeta[0]) * (x[0] - zeta[0]);
        /* the broadcast input of the build's predictor (what the plant integrates first) */
        rc |= dc_motor_link_broadcast(u, v, x, w);
        plant(zeta, w);
        for (i = 0; i < DC_MOTOR_LINK_NNODES; i++) {
            rc |= dc_motor_link_node_predict(&nodes[i], w);
        }
        rc |= dc_motor_link_master_predict(&master, w);
    }
    for (i = 0; i < DC_MOTOR_LINK_NNODES; i++) {
        dc_motor_link_health h;
        rc |= dc_motor_link_node_health(&nodes[i], &h);
        printf("node %d: updates %lu, drops %lu, late applied %lu, late rejected %lu\n", i,
               (unsigned long)h.updates, (unsigned long)h.drops, (unsigned long)h.late_applied,
               (unsigned long)h.late_rejected);
    }
    printf("control: %lu saturated inputs\n", (unsigned long)saturated);
    printf("RMS error of y1 (fused): %.3e\n", (double)SQRT(sq_err / (real)STEPS));
    return (rc == DC_MOTOR_LINK_OK && SQRT(sq_err / (real)STEPS) < 0.01) ? 0 : 1;
}
