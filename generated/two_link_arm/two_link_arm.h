/* DO NOT EDIT: two_link_arm module, generated from template model.h.j2 by dfeif-codegen 0.1.0;
 * regenerate with `codegen build two_link_arm`. */
/**
 * @file two_link_arm.h
 * @brief Distributed derivative-free Kalman filtering for the flat model `two_link_arm`.
 *
 * planar 2-DOF arm, a DC motor at each joint, joint angles measured by cameras
 *
 * The filters run on the canonical (Brunovsky) state zeta = [q1_0, q1_1, q1_2, q2_0, q2_1, q2_2],
 * chain by chain; each chain's first entry is a measured flat output.
 * They predict with the applied input u held over the period, as the plant holds it: the mean by
 * the canonical dynamics dzeta/dt = A_c zeta + B_c (F(zeta) + G(zeta) u) sampled by a fixed
 * exponential integrator, the covariance by constant matrices (predictor "held"). u is computed
 * at the master by two_link_arm_control() and broadcast: every node predicts with the same u.
 *
 * Conventions
 * - Scalars are two_link_arm_real (double). Matrices are row-major arrays: A[i * cols + j].
 * - All state lives in caller-owned structs: no malloc, no static mutable data, no stdio.
 *   Functions are reentrant; separate structs are independent instances.
 * - Every int function returns TWO_LINK_ARM_OK or a negative TWO_LINK_ARM_ERR_* code.
 *   On an error the struct is left bit-for-bit unchanged, except that a late measurement rejected
 *   for its lag or as a duplicate increments health.late_rejected.
 * - Steps are counted by uint32_t (2^32 steps: 497 days at 100 Hz).
 */
#ifndef TWO_LINK_ARM_H
#define TWO_LINK_ARM_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- dimensions and build options ---------------------------------------------------------- */
/** the filters' state dimension: the canonical state, then disturbance states (if built with) */
#define TWO_LINK_ARM_NX 6
/** canonical state dimension n (control gains, reference flags) */
#define TWO_LINK_ARM_NZ 6
/** process-noise densities q: one per chain, then one per disturbance state */
#define TWO_LINK_ARM_NQ 2
/** entries of an NX x NX matrix */
#define TWO_LINK_ARM_NXX (TWO_LINK_ARM_NX * TWO_LINK_ARM_NX)
/** measured flat outputs (= inputs) m */
#define TWO_LINK_ARM_NY 2
/** entries of an NY x NY matrix */
#define TWO_LINK_ARM_NYY (TWO_LINK_ARM_NY * TWO_LINK_ARM_NY)
/** physical inputs */
#define TWO_LINK_ARM_NU 2
/** model parameters (a runtime vector; nominal values in two_link_arm_params_default) */
#define TWO_LINK_ARM_NP 11
/** length of a parameter array: NP, at least 1 (a C array has at least one element; without
 * parameters its one entry is unused) */
#define TWO_LINK_ARM_NP_SLOTS 11
/** reference flags: per chain y_d, y_d', ..., y_d^(r) */
#define TWO_LINK_ARM_NFLAGS 8
/** |det G| at the nominal state, nominal parameters */
#define TWO_LINK_ARM_DET_NOMINAL 9661835.748792259
/* settable: codegen build --singular-rtol, or -D at compile time */
#ifndef TWO_LINK_ARM_SINGULAR_RTOL
/** control refuses below this fraction of DET_NOMINAL */
#define TWO_LINK_ARM_SINGULAR_RTOL 1e-06
#endif
/** 1: node_predict and master_predict take the applied u (predictor "held"); 0: they take v */
#define TWO_LINK_ARM_PREDICTS_WITH_U 1
/** 1: they take u, then the master's fused flat outputs sigma (predictor "scheduled"; NW = 2 NY) */
#define TWO_LINK_ARM_SCHEDULED 0
/** late-measurement window: lags 1..NMAX steps */
#define TWO_LINK_ARM_NMAX 32
/** slots of a node's ring: steps k-NMAX..k */
#define TWO_LINK_ARM_NRING (TWO_LINK_ARM_NMAX + 1)
/** reals of the input node_predict and master_predict take: u */
#define TWO_LINK_ARM_NW 2
/** NRING x NW and NMAX x NW (sizes of the rings of inputs) */
#define TWO_LINK_ARM_NRING_NW (TWO_LINK_ARM_NRING * TWO_LINK_ARM_NW)
#define TWO_LINK_ARM_NMAX_NW (TWO_LINK_ARM_NMAX * TWO_LINK_ARM_NW)
/** NRING x NY (the size of the ring of measurements) */
#define TWO_LINK_ARM_NRING_NY (TWO_LINK_ARM_NRING * TWO_LINK_ARM_NY)
/** camera nodes fused by the master */
#define TWO_LINK_ARM_NNODES 2
/** sampling period [s] */
#define TWO_LINK_ARM_TS 0.01
/** Newton steps of covariance intersection */
#define TWO_LINK_ARM_CI_ITERATIONS 8
#define TWO_LINK_ARM_PRECISION_FLOAT 0
/** 0: replay (exact), 1: retrodiction */
#define TWO_LINK_ARM_OOSM_RETRODICT 0
#define TWO_LINK_ARM_FUSION_PAPER 0
#define TWO_LINK_ARM_FUSION_DIFFERENCE 1
#define TWO_LINK_ARM_FUSION_CI 0
#define TWO_LINK_ARM_MODEL_HASH "14ea0cbc80df296882b0d092fcd543c05aaf2b02aac294913c7f9ca069a9d817"

/* Chains of the canonical state (initializers for int arrays of NY entries): degree, offset
 * (= index of each output in zeta), angle (1: innovations wrapped to (-pi, pi]). clang-format
 * cannot lay out a braced initializer in a macro, so it leaves these three lines alone. */
/* clang-format off */
#define TWO_LINK_ARM_CHAIN_DEGREES {3, 3}
#define TWO_LINK_ARM_CHAIN_OFFSETS {0, 3}
#define TWO_LINK_ARM_CHAIN_ANGLE {1, 1}
/* clang-format on */

/* Index of each parameter in params[NP] (the library's default table is laid out by them). */
/** m1 [kg]: mass at the tip of link 1 (elbow motor included) */
#define TWO_LINK_ARM_P_m1 0
/** m2 [kg]: mass at the tip of link 2 */
#define TWO_LINK_ARM_P_m2 1
/** l1 [m]: length of link 1 */
#define TWO_LINK_ARM_P_l1 2
/** l2 [m]: length of link 2 */
#define TWO_LINK_ARM_P_l2 3
/** Jm1 [kg*m^2]: shoulder rotor and gear inertia referred to the joint */
#define TWO_LINK_ARM_P_Jm1 4
/** Jm2 [kg*m^2]: elbow rotor and gear inertia referred to the joint */
#define TWO_LINK_ARM_P_Jm2 5
/** k_e [N*m/A]: torque (= back-EMF) constant at each joint, gear included */
#define TWO_LINK_ARM_P_k_e 6
/** k_d [N*m*s/rad]: viscous friction at each joint */
#define TWO_LINK_ARM_P_k_d 7
/** R [ohm]: armature resistance of each motor */
#define TWO_LINK_ARM_P_R 8
/** L [H]: armature inductance of each motor */
#define TWO_LINK_ARM_P_L 9
/** g [m/s^2]: gravity */
#define TWO_LINK_ARM_P_g 10

typedef double two_link_arm_real;

/* The constants above that are not integers, as objects (for callers without this header, e.g.
 * Python ctypes): TS, MODEL_HASH and CHAIN_ANGLE. */
extern const two_link_arm_real two_link_arm_ts;
extern const char two_link_arm_model_hash[65];
extern const uint8_t two_link_arm_chain_angle[TWO_LINK_ARM_NY];

/* ---- return codes ---------------------------------------------------------------------------- */
#define TWO_LINK_ARM_OK 0
/** NULL pointer, gamma or present[] not 0/1, q < 0, R not symmetric, P0 not SPD, x0 outside
 * the model's domain */
#define TWO_LINK_ARM_ERR_ARG (-1)
/** late measurement outside the window (lag < 1, > NMAX, before step 0 or a mid-run start) */
#define TWO_LINK_ARM_ERR_LAG (-2)
/** NaN or infinity in an input or a result */
#define TWO_LINK_ARM_ERR_NONFINITE (-3)
/** a matrix that must be positive definite (or invertible) is not */
#define TWO_LINK_ARM_ERR_SINGULAR (-4)
/** that step already has a measurement */
#define TWO_LINK_ARM_ERR_DUPLICATE (-5)
/** protocol order: update twice in a step, predict or late before update */
#define TWO_LINK_ARM_ERR_SEQUENCE (-6)

/** Node health counters. */
typedef struct {
    /** steps with an on-time measurement (gamma = 1) */
    uint32_t updates;
    /** steps without one (gamma = 0) */
    uint32_t drops;
    /** late measurements folded in */
    uint32_t late_applied;
    /** late measurements refused: lag out of window or duplicate */
    uint32_t late_rejected;
    /** measurements, on time or late, the innovation gate refused (0 without --gate) */
    uint32_t outliers;
} two_link_arm_health;

/** reals of a packed symmetric NX x NX matrix: its upper triangle, column by column */
#define TWO_LINK_ARM_NPP ((TWO_LINK_ARM_NX * (TWO_LINK_ARM_NX + 1)) / 2)
/** a node keeps the P prior of every CHECK_EVERY-th step and recomputes the ones between */
#define TWO_LINK_ARM_NODE_CHECK_EVERY 4u
/** checkpoints, (NMAX + CHECK_EVERY - 1) / CHECK_EVERY + 1: enough to hold the one at or before
 * the oldest step of the window */
#define TWO_LINK_ARM_NODE_NCHECK 9u
/** flags kept, NMAX + CHECK_EVERY: the window and the steps back to the checkpoint it needs */
#define TWO_LINK_ARM_NODE_NHIST 36u
/** reals of the checkpoints, NCHECK * NPP */
#define TWO_LINK_ARM_NODE_NCHECK_REALS 189

/**
 * One camera node's filter. Treat as opaque; read it through the functions below.
 * The ring holds steps k-NMAX..k, step j in slot j % (NMAX + 1): the prior of the step, its
 * measurement and the input (u) used to predict out of it. Estimates, priors and measurements are
 * stored relative to `centre` (one value per flat output, a whole number of its step, kept
 * within half a step of the estimate), so that single precision resolves the flat outputs to
 * their own size, not to that of the distance travelled; the functions below add it back.
 * The steps: 1/8, 1/8.
 */
typedef struct {
    /** flat outputs' origin for the fields below */
    two_link_arm_real centre[TWO_LINK_ARM_NY];
    /** estimate at step k (posterior once updated): x, then P packed */
    two_link_arm_real post[TWO_LINK_ARM_NX + TWO_LINK_ARM_NPP];
    /** prediction into step k, before any update (the prior of step k): x, then P packed */
    two_link_arm_real pred[TWO_LINK_ARM_NX + TWO_LINK_ARM_NPP];
    /** measurement covariance */
    two_link_arm_real R[TWO_LINK_ARM_NYY];
    /** process-noise density per chain */
    two_link_arm_real q[TWO_LINK_ARM_NQ];
    /** the process noise of one period the predictions add, Q0 of q (upper triangle packed) */
    two_link_arm_real Qd[TWO_LINK_ARM_NPP];
    two_link_arm_real ring_x[TWO_LINK_ARM_NRING * TWO_LINK_ARM_NX];
    two_link_arm_real ring_z[TWO_LINK_ARM_NRING_NY];
    two_link_arm_real ring_v[TWO_LINK_ARM_NRING_NW];
    /** packed P priors of the checkpoint steps (multiples of CHECK_EVERY), the latest at or
     * before k at entry `check`, each earlier one at the entry before (cyclically) */
    two_link_arm_real ring_P[TWO_LINK_ARM_NODE_NCHECK_REALS];
    /** current step (modulo 2^32: it wraps), its slot in the rings (of NRING), its flags' entry
     * (of NHIST) and its latest checkpoint's entry (of NCHECK): each advanced with k, and a step
     * of the window found by its distance back from k, so no index depends on k itself */
    uint32_t k;
    uint16_t slot;
    uint16_t hist;
    uint16_t check;
    two_link_arm_health health;
    /** how far back a late frame may reach: steps since init or, after node_mid_run(), since
     * update() applied the first measurement (a replay before it would correct the start-up prior
     * alone); counts up to NHIST and stays there */
    uint32_t age;
    uint8_t measured;
    /** update() done for step k */
    uint8_t updated;
    /** per step, at step % NHIST: bit 0 has a measurement, bit 1 used by the filter */
    uint8_t ring_flags[TWO_LINK_ARM_NODE_NHIST];
} two_link_arm_node;

/** What a node sends to the master after the updates of its step: its estimate and its
 * prediction, with the flat outputs relative to `centre` (add it back for absolute values). */
typedef struct {
    uint32_t step;
    two_link_arm_real centre[TWO_LINK_ARM_NY];
    two_link_arm_real x[TWO_LINK_ARM_NX];
    two_link_arm_real P[TWO_LINK_ARM_NXX];
    two_link_arm_real x_pred[TWO_LINK_ARM_NX];
    two_link_arm_real P_pred[TWO_LINK_ARM_NXX];
} two_link_arm_packet;

/** Master health counters. */
typedef struct {
    /** successful fuse() calls */
    uint32_t fusions;
    /** packets fused */
    uint32_t packets_used;
    /** of those, packets predicted forward from an older step */
    uint32_t packets_stale;
    /** present packets older than NMAX steps or from the future, or not newer than the last one
     * fused from their node */
    uint32_t packets_ignored;
} two_link_arm_master_health;

/** The master: fuses the nodes' estimates (difference rule) and predicts. Its estimate and
 * prediction are stored relative to `centre`, as in the node. */
typedef struct {
    /** flat outputs' origin for x and x_prior */
    two_link_arm_real centre[TWO_LINK_ARM_NY];
    /** fused estimate at step k */
    two_link_arm_real x[TWO_LINK_ARM_NX];
    two_link_arm_real P[TWO_LINK_ARM_NXX];
    /** the master's own prediction into step k */
    two_link_arm_real x_prior[TWO_LINK_ARM_NX];
    two_link_arm_real P_prior[TWO_LINK_ARM_NXX];
    two_link_arm_real q[TWO_LINK_ARM_NQ];
    /** Q0 of q, as the node's */
    two_link_arm_real Qd[TWO_LINK_ARM_NPP];
    /** inputs (u) of steps k-NMAX..k-1, step k-d in slot (vslot - d) mod NMAX */
    two_link_arm_real v[TWO_LINK_ARM_NMAX_NW];
    /** current step (modulo 2^32: it wraps; a packet's age is k - step modulo 2^32), and the slot
     * its input will take */
    uint32_t k;
    uint32_t vslot;
    /** steps since init, up to NMAX and then staying there: no packet is from before step 0 */
    uint32_t age;
    /** per node, the last packet fused (its step, centre, x and P; last_valid 0 before the
     * first): where that node's packets were lost since, its next gain is taken over this
     * estimate brought forward (a channel filter, docs/algorithms.md) */
    uint32_t last_step[TWO_LINK_ARM_NNODES];
    two_link_arm_real last_centre[TWO_LINK_ARM_NNODES * TWO_LINK_ARM_NY];
    two_link_arm_real last_x[TWO_LINK_ARM_NNODES * TWO_LINK_ARM_NX];
    two_link_arm_real last_P[TWO_LINK_ARM_NNODES * TWO_LINK_ARM_NXX];
    uint8_t last_valid[TWO_LINK_ARM_NNODES];
    two_link_arm_master_health health;
} two_link_arm_master;

/** Model parameters at their nominal values (model order, see TWO_LINK_ARM_P_*). */
extern const two_link_arm_real two_link_arm_params_default[TWO_LINK_ARM_NP_SLOTS];

/* sizeof, for callers that allocate without this header (e.g. Python ctypes). */
size_t two_link_arm_node_size(void);
size_t two_link_arm_master_size(void);
size_t two_link_arm_packet_size(void);

/* ---- node ------------------------------------------------------------------------------- */
/** Start at step 0 with prior (x0, P0); R (NY x NY) symmetric positive definite, q >= 0.
 * ERR_ARG if the model is not defined at x0 (F-bar or G-bar not finite): no input predicts out of
 * it, and it is no state of the model (a finite value, so not ERR_NONFINITE). */
int two_link_arm_node_init(two_link_arm_node* node, const two_link_arm_real x0[TWO_LINK_ARM_NX],
                           const two_link_arm_real P0[TWO_LINK_ARM_NXX],
                           const two_link_arm_real R[TWO_LINK_ARM_NYY],
                           const two_link_arm_real q[TWO_LINK_ARM_NQ]);
/** Right after init, for a node started mid-run (its prior is the one of step 0, not of the
 * step it starts at): late frames of steps before its first measurement are then refused
 * (ERR_LAG). ERR_SEQUENCE after the first update. */
int two_link_arm_node_mid_run(two_link_arm_node* node);
/** The measurement of step k (gamma = 1) or its loss (gamma = 0, z may be NULL). Once per step:
 * after an error the step is not updated, and the caller may call again (gamma = 0 to go on
 * without the measurement). */
int two_link_arm_node_update(two_link_arm_node* node, const two_link_arm_real z[TWO_LINK_ARM_NY],
                             int gamma);
/** A measurement taken at step k - lag, after update() of step k (replay). */
int two_link_arm_node_update_delayed(two_link_arm_node* node,
                                     const two_link_arm_real z[TWO_LINK_ARM_NY], int32_t lag);
/** Predict to step k + 1 (after update() of step k) with the broadcast input: u. */
int two_link_arm_node_predict(two_link_arm_node* node,
                              const two_link_arm_real input[TWO_LINK_ARM_NW]);
/** Current estimate; either output may be NULL. */
int two_link_arm_node_estimate(const two_link_arm_node* node, two_link_arm_real x[TWO_LINK_ARM_NX],
                               two_link_arm_real P[TWO_LINK_ARM_NXX]);
/** Information form Y = P^-1, y = Y x (Cholesky); either output may be NULL. */
int two_link_arm_node_information(const two_link_arm_node* node,
                                  two_link_arm_real Y[TWO_LINK_ARM_NXX],
                                  two_link_arm_real y[TWO_LINK_ARM_NX]);
/** The packet for the master: step, x, P, x_pred, P_pred. */
int two_link_arm_node_packet(const two_link_arm_node* node, two_link_arm_packet* packet);
int two_link_arm_node_health(const two_link_arm_node* node, two_link_arm_health* health);

/* ---- master ----------------------------------------------------------------------------- */
/** Start at step 0 with prior (x0, P0) and the process-noise densities q; ERR_ARG if the
 * model is not defined at x0, as for node_init. */
int two_link_arm_master_init(two_link_arm_master* master,
                             const two_link_arm_real x0[TWO_LINK_ARM_NX],
                             const two_link_arm_real P0[TWO_LINK_ARM_NXX],
                             const two_link_arm_real q[TWO_LINK_ARM_NQ]);
/**
 * Fuse the packets of step k. present[i] = 0 leaves node i out; a packet from an older step is
 * predicted to k with the stored inputs, one older than NMAX steps or from the future is ignored.
 * With no packet the estimate is the master's prediction. May be called again in the same step:
 * information adds, so a call adds the packets not yet fused to the estimate (one already fused
 * is ignored): fuse packets as they arrive.
 * A present packet whose P or P_pred is not symmetric positive definite, or (difference rule)
 * whose P exceeds P_pred on the diagonal, refuses the call (ERR_SINGULAR).
 */
int two_link_arm_master_fuse(two_link_arm_master* master,
                             const two_link_arm_packet packets[TWO_LINK_ARM_NNODES],
                             const uint8_t present[TWO_LINK_ARM_NNODES]);
/** Predict to step k + 1 with the broadcast input (u), as the nodes. */
int two_link_arm_master_predict(two_link_arm_master* master,
                                const two_link_arm_real input[TWO_LINK_ARM_NW]);
/** Fused estimate; either output may be NULL. */
int two_link_arm_master_estimate(const two_link_arm_master* master,
                                 two_link_arm_real x[TWO_LINK_ARM_NX],
                                 two_link_arm_real P[TWO_LINK_ARM_NXX]);

/* ---- wire (docs/wire.md) ------------------------------------------------------------------- */
/* Fixed-size little-endian frames: a 32-byte header (magic "DFEW", version, kind, flags, bytes per
 * real, model hash prefix, node id, reals in the payload, step, sequence number, epoch), the
 * payload, a SipHash-2-4 tag (zero without a key) and a CRC-32 (IEEE, = zlib.crc32 of the bytes
 * before it). The epoch is the master's boot: its commands and announcements carry it, the
 * nodes' packets echo the last one they heard, and a keyed master takes only its own. */
#define TWO_LINK_ARM_WIRE_VERSION 3u
#define TWO_LINK_ARM_WIRE_HEADER 32u
/** bytes of a frame of n reals: header, n reals of 8 bytes, tag (8) and CRC (4) */
#define TWO_LINK_ARM_FRAME_SIZE(n) (44u + (8u * (size_t)(n)))
/** node -> master: a two_link_arm_packet */
#define TWO_LINK_ARM_KIND_PACKET 1u
/** master -> nodes and actuator: (k, v, u) */
#define TWO_LINK_ARM_KIND_COMMAND 2u
/** master -> nodes: its epoch, no reals (a master that cannot command yet: restarted) */
#define TWO_LINK_ARM_KIND_ANNOUNCE 5u
/** node id field of the master's frames */
#define TWO_LINK_ARM_MASTER_ID 0xFFFFu
/** reals in a packet (NY + 2 NX + 2 NX^2) */
#define TWO_LINK_ARM_PACKET_REALS 86
/** reals after v in a command: u */
#define TWO_LINK_ARM_NU_WIRE TWO_LINK_ARM_NU
/** reals in a command: v, u */
#define TWO_LINK_ARM_COMMAND_REALS (TWO_LINK_ARM_NY + TWO_LINK_ARM_NU_WIRE)
/** FRAME_SIZE(PACKET_REALS) */
#define TWO_LINK_ARM_PACKET_WIRE_SIZE 732u
/** FRAME_SIZE(COMMAND_REALS) */
#define TWO_LINK_ARM_COMMAND_WIRE_SIZE 76u
/** FRAME_SIZE(0) */
#define TWO_LINK_ARM_ANNOUNCE_WIRE_SIZE 44u
/** frame of the wrong size */
#define TWO_LINK_ARM_ERR_WIRE_LENGTH (-10)
/** CRC-32 mismatch: corrupted on the way */
#define TWO_LINK_ARM_ERR_WIRE_CRC (-11)
/** not a frame of this kind: magic, kind, real size or count */
#define TWO_LINK_ARM_ERR_WIRE_FORMAT (-12)
/** another wire format version */
#define TWO_LINK_ARM_ERR_WIRE_VERSION (-13)
/** another model (hash prefix) */
#define TWO_LINK_ARM_ERR_WIRE_MODEL (-14)
/** keyed tag missing or wrong */
#define TWO_LINK_ARM_ERR_WIRE_TAG (-15)
/** unknown node id */
#define TWO_LINK_ARM_ERR_WIRE_NODE (-16)
/** that (node, step) was already received */
#define TWO_LINK_ARM_ERR_WIRE_DUPLICATE (-17)
/** older than the window (or than the master's start) */
#define TWO_LINK_ARM_ERR_WIRE_OLD (-18)
/** from a step the master has not reached */
#define TWO_LINK_ARM_ERR_WIRE_FUTURE (-19)
/** keyed: sequence number not above the last one */
#define TWO_LINK_ARM_ERR_WIRE_REPLAY (-20)
/** older than a packet already received from that node */
#define TWO_LINK_ARM_ERR_WIRE_OUTDATED (-21)
/** A packet's P or P_pred is not symmetric positive definite. */
#define TWO_LINK_ARM_ERR_WIRE_COVARIANCE (-22)
/** A packet's P exceeds its P_pred on the diagonal (difference rule: a negative gain). */
#define TWO_LINK_ARM_ERR_WIRE_GAIN (-23)
/** keyed: another epoch than the master's (a frame of an earlier boot, or a node not yet told) */
#define TWO_LINK_ARM_ERR_WIRE_EPOCH (-24)

typedef struct {
    uint8_t kind;
    uint16_t node;
    uint32_t step;
    uint32_t seq;
    uint32_t epoch;
} two_link_arm_frame_header;

/** Rejected frames per cause. */
typedef struct {
    uint32_t length;
    uint32_t crc;
    uint32_t format;
    uint32_t version;
    uint32_t model;
    uint32_t tag;
    uint32_t node;
    uint32_t duplicate;
    uint32_t old;
    uint32_t future;
    uint32_t replay;
    uint32_t outdated;
    uint32_t nonfinite;
    uint32_t covariance;
    uint32_t gain;
    uint32_t epoch;
    uint32_t unfused; /* staged, but the fuse could not use it (dropped, the others fused) */
    uint32_t other;
} two_link_arm_wire_counters;

/** The master's receive side: checked packets staged for the next fuse, per-node last step and
 * sequence number, the deployment key, the master's epoch and what was rejected. `base` is the
 * global step of the master's step 0 (a restarted master starts at the step it rejoins). */
typedef struct {
    two_link_arm_packet staged[TWO_LINK_ARM_NNODES];
    uint8_t present[TWO_LINK_ARM_NNODES];
    uint8_t seen[TWO_LINK_ARM_NNODES];
    uint32_t last_step[TWO_LINK_ARM_NNODES];
    uint32_t last_seq[TWO_LINK_ARM_NNODES];
    uint32_t base;
    uint32_t epoch;
    uint32_t accepted;
    uint8_t key[16];
    uint8_t keyed;
    two_link_arm_wire_counters rejected;
} two_link_arm_inbox;

/** A node's receive side for the master's commands and announcements: the master's epoch as
 * last heard (the node's packets carry it) and the last sequence number in that epoch. */
typedef struct {
    uint32_t epoch;
    uint32_t last_seq;
    uint32_t accepted;
    uint8_t seen;
    uint8_t key[16];
    uint8_t keyed;
    two_link_arm_wire_counters rejected;
} two_link_arm_command_rx;

/** CRC-32 of len bytes (data NULL: 0, the CRC of none). */
uint32_t two_link_arm_crc32(const uint8_t* data, size_t len);
/** SipHash-2-4 of len bytes under key (key NULL, or data NULL with len > 0: 0). */
uint64_t two_link_arm_siphash24(const uint8_t key[16], const uint8_t* data, size_t len);
/** Any frame: header fields, `count` reals; key NULL = CRC only. buf holds FRAME_SIZE(count)
 * bytes. */
int two_link_arm_frame_encode(const two_link_arm_frame_header* header,
                              const two_link_arm_real* values, uint16_t count, const uint8_t* key,
                              uint8_t* buf, size_t cap);
/** Checks size, CRC, magic/kind/count, version, model, tag (if key), finiteness; then fills
 * values. */
int two_link_arm_frame_decode(const uint8_t* buf, size_t len, const uint8_t* key, uint8_t kind,
                              two_link_arm_real* values, uint16_t count,
                              two_link_arm_frame_header* header);
/** epoch: the master's, as the node last heard it (its command_rx's `epoch`). */
int two_link_arm_packet_encode(const two_link_arm_packet* packet, uint16_t node, uint32_t seq,
                               uint32_t epoch, const uint8_t* key,
                               uint8_t buf[TWO_LINK_ARM_PACKET_WIRE_SIZE]);
int two_link_arm_packet_decode(const uint8_t* buf, size_t len, const uint8_t* key,
                               two_link_arm_packet* packet, two_link_arm_frame_header* header);
/** epoch: the master's (as given to inbox_init). */
int two_link_arm_command_encode(uint32_t step, const two_link_arm_real v[TWO_LINK_ARM_NY],
                                const two_link_arm_real u[TWO_LINK_ARM_NU_WIRE], uint32_t seq,
                                uint32_t epoch, const uint8_t* key,
                                uint8_t buf[TWO_LINK_ARM_COMMAND_WIRE_SIZE]);
/** The master's epoch without a command (a restarted master, before it can command). */
int two_link_arm_announce_encode(uint32_t step, uint32_t seq, uint32_t epoch, const uint8_t* key,
                                 uint8_t buf[TWO_LINK_ARM_ANNOUNCE_WIRE_SIZE]);
int two_link_arm_command_decode(const uint8_t* buf, size_t len, const uint8_t* key,
                                two_link_arm_real v[TWO_LINK_ARM_NY],
                                two_link_arm_real u[TWO_LINK_ARM_NU_WIRE],
                                two_link_arm_frame_header* header);
/** key NULL: CRC only; base: global step of the master's step 0; epoch: this boot's, chosen by the
 * caller and never used before under this key (a boot counter kept in non-volatile memory,
 * incremented at every boot: the nodes take a newer epoch, RFC 1982 order, and refuse older
 * ones). */
int two_link_arm_inbox_init(two_link_arm_inbox* inbox, const uint8_t key[16], uint32_t base,
                            uint32_t epoch);
/** A restarted master's first packet: the checks of master_receive that need no master state
 * (integrity, node id, keyed: the epoch, covariances), counted per cause. OK: the
 * packet (its step global) to initialise from; stage it afterwards with master_receive. */
int two_link_arm_inbox_join(two_link_arm_inbox* inbox, const uint8_t* buf, size_t len,
                            two_link_arm_packet* packet, two_link_arm_frame_header* header);
/** Check a received frame (integrity, identity, window, duplicates, replay, then the packet's
 * covariances as master_fuse needs them) and stage it for the next fuse; a rejected frame is
 * counted per cause and changes nothing else (its node's packet for that step is still taken). */
int two_link_arm_master_receive(const two_link_arm_master* master, two_link_arm_inbox* inbox,
                                const uint8_t* buf, size_t len);
/** Fuse the staged packets (master_fuse), then clear them. If that fails (ERR_SINGULAR or
 * ERR_NONFINITE), the packets are added one by one in node order, each one whose addition
 * cannot be fused is dropped (counted: unfused), and the rest are fused: one bad packet costs
 * only its own node. */
int two_link_arm_master_fuse_inbox(two_link_arm_master* master, two_link_arm_inbox* inbox);
size_t two_link_arm_inbox_size(void);
size_t two_link_arm_command_rx_size(void);
/** The rejection counters of an inbox (or, with inbox NULL, of a command receiver). */
int two_link_arm_wire_rejected(const two_link_arm_inbox* inbox, const two_link_arm_command_rx* rx,
                               two_link_arm_wire_counters* out);
/** epoch: the latest master epoch this node has heard, kept by the caller across the node's own
 * restarts (0 if none): with a key, commands of an older epoch are refused. */
int two_link_arm_command_rx_init(two_link_arm_command_rx* rx, const uint8_t key[16],
                                 uint32_t epoch);
/** Check a command frame (integrity, from the master; keyed: an epoch not older than the last
 * one heard, a newer one taken, and within it a fresh sequence number). */
int two_link_arm_command_receive(two_link_arm_command_rx* rx, const uint8_t* buf, size_t len,
                                 uint32_t* step, two_link_arm_real v[TWO_LINK_ARM_NY],
                                 two_link_arm_real u[TWO_LINK_ARM_NU_WIRE]);
/** Check an announcement (as command_receive) and take its epoch. */
int two_link_arm_announce_receive(two_link_arm_command_rx* rx, const uint8_t* buf, size_t len);

/* ---- control ---------------------------------------------------------------------------- */
/**
 * Flatness-based control: v_j = y_d^(r) - sum_i k_(r-i) e_i on each chain (heads wrapped for
 * angles), u = G(x)^-1 (v - F(x)). gains per chain [k_1 .. k_r] (see two_link_arm_gains).
 * v may be NULL. ERR_SINGULAR when |det G(x)| < SINGULAR_RTOL * DET_NOMINAL (G at the nominal
 * state). Declared input limits clamp u; *saturated (may be NULL) is incremented by the inputs
 * clamped.
 */
int two_link_arm_control(const two_link_arm_real x[TWO_LINK_ARM_NX],
                         const two_link_arm_real flags[TWO_LINK_ARM_NFLAGS],
                         const two_link_arm_real gains[TWO_LINK_ARM_NZ],
                         const two_link_arm_real params[TWO_LINK_ARM_NP_SLOTS],
                         two_link_arm_real u[TWO_LINK_ARM_NU], two_link_arm_real v[TWO_LINK_ARM_NY],
                         uint32_t* saturated);
/** Gains placing all poles of chain j at -lambda[j]:
 * s^r + k_1 s^(r-1) + ... + k_r = (s + lambda)^r. A lambda[j] <= 0 (not stable) is ERR_ARG. */
int two_link_arm_gains(const two_link_arm_real lambda[TWO_LINK_ARM_NY],
                       two_link_arm_real gains[TWO_LINK_ARM_NZ]);
/** The input every node_predict and master_predict of the step takes, which the master
 * broadcasts: u, from control's u and v and the
 * master's fused estimate x (master_estimate's, absolute). */
int two_link_arm_broadcast(const two_link_arm_real u[TWO_LINK_ARM_NU],
                           const two_link_arm_real v[TWO_LINK_ARM_NY],
                           const two_link_arm_real x[TWO_LINK_ARM_NX],
                           two_link_arm_real w[TWO_LINK_ARM_NW]);

#ifdef __cplusplus
}
#endif

#endif /* TWO_LINK_ARM_H */
