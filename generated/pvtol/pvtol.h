/* DO NOT EDIT: pvtol module, generated from template model.h.j2 by dfeif-codegen 0.1.0;
 * regenerate with `codegen build pvtol`. */
/**
 * @file pvtol.h
 * @brief Distributed derivative-free Kalman filtering for the flat model `pvtol`.
 *
 * planar quadrotor, thrust and torque inputs, position seen by wall cameras
 *
 * The filters run on the canonical (Brunovsky) state zeta = [px_0, px_1, px_2, px_3, pz_0, pz_1,
 * pz_2, pz_3],
 * chain by chain; each chain's first entry is a measured flat output.
 * They predict with the applied input u held over the period, as the plant holds it: the mean by
 * the canonical dynamics dzeta/dt = A_c zeta + B_c (F(zeta) + G(zeta) u) sampled by a fixed
 * exponential integrator, the covariance by constant matrices (predictor "held"). u is computed
 * at the master by pvtol_control() and broadcast: every node predicts with the same u.
 *
 * Conventions
 * - Scalars are pvtol_real (double). Matrices are row-major arrays: A[i * cols + j].
 * - All state lives in caller-owned structs: no malloc, no static mutable data, no stdio.
 *   Functions are reentrant; separate structs are independent instances.
 * - Every int function returns PVTOL_OK or a negative PVTOL_ERR_* code.
 *   On an error the struct is left bit-for-bit unchanged, except that a late measurement rejected
 *   for its lag or as a duplicate increments health.late_rejected.
 * - Steps are counted by uint32_t (2^32 steps: 497 days at 100 Hz).
 */
#ifndef PVTOL_H
#define PVTOL_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- dimensions and build options ---------------------------------------------------------- */
/** the filters' state dimension: the canonical state, then disturbance states (if built with) */
#define PVTOL_NX 8
/** canonical state dimension n (control gains, reference flags) */
#define PVTOL_NZ 8
/** process-noise densities q: one per chain, then one per disturbance state */
#define PVTOL_NQ 2
/** entries of an NX x NX matrix */
#define PVTOL_NXX (PVTOL_NX * PVTOL_NX)
/** measured flat outputs (= inputs) m */
#define PVTOL_NY 2
/** entries of an NY x NY matrix */
#define PVTOL_NYY (PVTOL_NY * PVTOL_NY)
/** physical inputs */
#define PVTOL_NU 2
/** model parameters (a runtime vector; nominal values in pvtol_params_default) */
#define PVTOL_NP 3
/** length of a parameter array: NP, at least 1 (a C array has at least one element; without
 * parameters its one entry is unused) */
#define PVTOL_NP_SLOTS 3
/** reference flags: per chain y_d, y_d', ..., y_d^(r) */
#define PVTOL_NFLAGS 10
/** |det G| at the nominal state, nominal parameters */
#define PVTOL_DET_NOMINAL 2802.8571428571418
/* settable: codegen build --singular-rtol, or -D at compile time */
#ifndef PVTOL_SINGULAR_RTOL
/** control refuses below this fraction of DET_NOMINAL */
#define PVTOL_SINGULAR_RTOL 1e-06
#endif
/** 1: node_predict and master_predict take the applied u (predictor "held"); 0: they take v */
#define PVTOL_PREDICTS_WITH_U 1
/** 1: they take u, then the master's fused flat outputs sigma (predictor "scheduled"; NW = 2 NY) */
#define PVTOL_SCHEDULED 0
/** late-measurement window: lags 1..NMAX steps */
#define PVTOL_NMAX 32
/** slots of a node's ring: steps k-NMAX..k */
#define PVTOL_NRING (PVTOL_NMAX + 1)
/** reals of the input node_predict and master_predict take: u */
#define PVTOL_NW 2
/** NRING x NW and NMAX x NW (sizes of the rings of inputs) */
#define PVTOL_NRING_NW (PVTOL_NRING * PVTOL_NW)
#define PVTOL_NMAX_NW (PVTOL_NMAX * PVTOL_NW)
/** NRING x NY (the size of the ring of measurements) */
#define PVTOL_NRING_NY (PVTOL_NRING * PVTOL_NY)
/** camera nodes fused by the master */
#define PVTOL_NNODES 2
/** sampling period [s] */
#define PVTOL_TS 0.01
/** Newton steps of covariance intersection */
#define PVTOL_CI_ITERATIONS 8
#define PVTOL_PRECISION_FLOAT 0
/** 0: replay (exact), 1: retrodiction */
#define PVTOL_OOSM_RETRODICT 0
#define PVTOL_FUSION_PAPER 0
#define PVTOL_FUSION_DIFFERENCE 1
#define PVTOL_FUSION_CI 0
#define PVTOL_MODEL_HASH "2d79929800dc1fc33d775c47c3df542430866a3727d5329d0b7b32381488e07e"

/* Chains of the canonical state (initializers for int arrays of NY entries): degree, offset
 * (= index of each output in zeta), angle (1: innovations wrapped to (-pi, pi]). clang-format
 * cannot lay out a braced initializer in a macro, so it leaves these three lines alone. */
/* clang-format off */
#define PVTOL_CHAIN_DEGREES {4, 4}
#define PVTOL_CHAIN_OFFSETS {0, 4}
#define PVTOL_CHAIN_ANGLE {0, 0}
/* clang-format on */

/* Index of each parameter in params[NP] (the library's default table is laid out by them). */
/** m [kg]: mass */
#define PVTOL_P_m 0
/** J [kg*m^2]: roll inertia */
#define PVTOL_P_J 1
/** g [m/s^2]: gravity */
#define PVTOL_P_g 2

typedef double pvtol_real;

/* The constants above that are not integers, as objects (for callers without this header, e.g.
 * Python ctypes): TS, MODEL_HASH and CHAIN_ANGLE. */
extern const pvtol_real pvtol_ts;
extern const char pvtol_model_hash[65];
extern const uint8_t pvtol_chain_angle[PVTOL_NY];

/* ---- return codes ---------------------------------------------------------------------------- */
#define PVTOL_OK 0
/** NULL pointer, gamma or present[] not 0/1, q < 0, R not symmetric, P0 not SPD, x0 outside
 * the model's domain */
#define PVTOL_ERR_ARG (-1)
/** late measurement outside the window (lag < 1, > NMAX, before step 0 or a mid-run start) */
#define PVTOL_ERR_LAG (-2)
/** NaN or infinity in an input or a result */
#define PVTOL_ERR_NONFINITE (-3)
/** a matrix that must be positive definite (or invertible) is not */
#define PVTOL_ERR_SINGULAR (-4)
/** that step already has a measurement */
#define PVTOL_ERR_DUPLICATE (-5)
/** protocol order: update twice in a step, predict or late before update */
#define PVTOL_ERR_SEQUENCE (-6)

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
} pvtol_health;

/** reals of a packed symmetric NX x NX matrix: its upper triangle, column by column */
#define PVTOL_NPP ((PVTOL_NX * (PVTOL_NX + 1)) / 2)
/** a node keeps the P prior of every CHECK_EVERY-th step and recomputes the ones between */
#define PVTOL_NODE_CHECK_EVERY 4u
/** checkpoints, (NMAX + CHECK_EVERY - 1) / CHECK_EVERY + 1: enough to hold the one at or before
 * the oldest step of the window */
#define PVTOL_NODE_NCHECK 9u
/** flags kept, NMAX + CHECK_EVERY: the window and the steps back to the checkpoint it needs */
#define PVTOL_NODE_NHIST 36u
/** reals of the checkpoints, NCHECK * NPP */
#define PVTOL_NODE_NCHECK_REALS 324

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
    pvtol_real centre[PVTOL_NY];
    /** estimate at step k (posterior once updated): x, then P packed */
    pvtol_real post[PVTOL_NX + PVTOL_NPP];
    /** prediction into step k, before any update (the prior of step k): x, then P packed */
    pvtol_real pred[PVTOL_NX + PVTOL_NPP];
    /** measurement covariance */
    pvtol_real R[PVTOL_NYY];
    /** process-noise density per chain */
    pvtol_real q[PVTOL_NQ];
    /** the process noise of one period the predictions add, Q0 of q (upper triangle packed) */
    pvtol_real Qd[PVTOL_NPP];
    pvtol_real ring_x[PVTOL_NRING * PVTOL_NX];
    pvtol_real ring_z[PVTOL_NRING_NY];
    pvtol_real ring_v[PVTOL_NRING_NW];
    /** packed P priors of the checkpoint steps (multiples of CHECK_EVERY), the latest at or
     * before k at entry `check`, each earlier one at the entry before (cyclically) */
    pvtol_real ring_P[PVTOL_NODE_NCHECK_REALS];
    /** current step (modulo 2^32: it wraps), its slot in the rings (of NRING), its flags' entry
     * (of NHIST) and its latest checkpoint's entry (of NCHECK): each advanced with k, and a step
     * of the window found by its distance back from k, so no index depends on k itself */
    uint32_t k;
    uint16_t slot;
    uint16_t hist;
    uint16_t check;
    pvtol_health health;
    /** how far back a late frame may reach: steps since init or, after node_mid_run(), since
     * update() applied the first measurement (a replay before it would correct the start-up prior
     * alone); counts up to NHIST and stays there */
    uint32_t age;
    uint8_t measured;
    /** update() done for step k */
    uint8_t updated;
    /** per step, at step % NHIST: bit 0 has a measurement, bit 1 used by the filter */
    uint8_t ring_flags[PVTOL_NODE_NHIST];
} pvtol_node;

/** What a node sends to the master after the updates of its step: its estimate and its
 * prediction, with the flat outputs relative to `centre` (add it back for absolute values). */
typedef struct {
    uint32_t step;
    pvtol_real centre[PVTOL_NY];
    pvtol_real x[PVTOL_NX];
    pvtol_real P[PVTOL_NXX];
    pvtol_real x_pred[PVTOL_NX];
    pvtol_real P_pred[PVTOL_NXX];
} pvtol_packet;

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
} pvtol_master_health;

/** The master: fuses the nodes' estimates (difference rule) and predicts. Its estimate and
 * prediction are stored relative to `centre`, as in the node. */
typedef struct {
    /** flat outputs' origin for x and x_prior */
    pvtol_real centre[PVTOL_NY];
    /** fused estimate at step k */
    pvtol_real x[PVTOL_NX];
    pvtol_real P[PVTOL_NXX];
    /** the master's own prediction into step k */
    pvtol_real x_prior[PVTOL_NX];
    pvtol_real P_prior[PVTOL_NXX];
    pvtol_real q[PVTOL_NQ];
    /** Q0 of q, as the node's */
    pvtol_real Qd[PVTOL_NPP];
    /** inputs (u) of steps k-NMAX..k-1, step k-d in slot (vslot - d) mod NMAX */
    pvtol_real v[PVTOL_NMAX_NW];
    /** current step (modulo 2^32: it wraps; a packet's age is k - step modulo 2^32), and the slot
     * its input will take */
    uint32_t k;
    uint32_t vslot;
    /** steps since init, up to NMAX and then staying there: no packet is from before step 0 */
    uint32_t age;
    /** per node, the last packet fused (its step, centre, x and P; last_valid 0 before the
     * first): where that node's packets were lost since, its next gain is taken over this
     * estimate brought forward (a channel filter, docs/algorithms.md) */
    uint32_t last_step[PVTOL_NNODES];
    pvtol_real last_centre[PVTOL_NNODES * PVTOL_NY];
    pvtol_real last_x[PVTOL_NNODES * PVTOL_NX];
    pvtol_real last_P[PVTOL_NNODES * PVTOL_NXX];
    uint8_t last_valid[PVTOL_NNODES];
    pvtol_master_health health;
} pvtol_master;

/** Model parameters at their nominal values (model order, see PVTOL_P_*). */
extern const pvtol_real pvtol_params_default[PVTOL_NP_SLOTS];

/* sizeof, for callers that allocate without this header (e.g. Python ctypes). */
size_t pvtol_node_size(void);
size_t pvtol_master_size(void);
size_t pvtol_packet_size(void);

/* ---- node ------------------------------------------------------------------------------- */
/** Start at step 0 with prior (x0, P0); R (NY x NY) symmetric positive definite, q >= 0.
 * ERR_ARG if the model is not defined at x0 (F-bar or G-bar not finite): no input predicts out of
 * it, and it is no state of the model (a finite value, so not ERR_NONFINITE). */
int pvtol_node_init(pvtol_node* node, const pvtol_real x0[PVTOL_NX], const pvtol_real P0[PVTOL_NXX],
                    const pvtol_real R[PVTOL_NYY], const pvtol_real q[PVTOL_NQ]);
/** Right after init, for a node started mid-run (its prior is the one of step 0, not of the
 * step it starts at): late frames of steps before its first measurement are then refused
 * (ERR_LAG). ERR_SEQUENCE after the first update. */
int pvtol_node_mid_run(pvtol_node* node);
/** The measurement of step k (gamma = 1) or its loss (gamma = 0, z may be NULL). Once per step:
 * after an error the step is not updated, and the caller may call again (gamma = 0 to go on
 * without the measurement). */
int pvtol_node_update(pvtol_node* node, const pvtol_real z[PVTOL_NY], int gamma);
/** A measurement taken at step k - lag, after update() of step k (replay). */
int pvtol_node_update_delayed(pvtol_node* node, const pvtol_real z[PVTOL_NY], int32_t lag);
/** Predict to step k + 1 (after update() of step k) with the broadcast input: u. */
int pvtol_node_predict(pvtol_node* node, const pvtol_real input[PVTOL_NW]);
/** Current estimate; either output may be NULL. */
int pvtol_node_estimate(const pvtol_node* node, pvtol_real x[PVTOL_NX], pvtol_real P[PVTOL_NXX]);
/** Information form Y = P^-1, y = Y x (Cholesky); either output may be NULL. */
int pvtol_node_information(const pvtol_node* node, pvtol_real Y[PVTOL_NXX], pvtol_real y[PVTOL_NX]);
/** The packet for the master: step, x, P, x_pred, P_pred. */
int pvtol_node_packet(const pvtol_node* node, pvtol_packet* packet);
int pvtol_node_health(const pvtol_node* node, pvtol_health* health);

/* ---- master ----------------------------------------------------------------------------- */
/** Start at step 0 with prior (x0, P0) and the process-noise densities q; ERR_ARG if the
 * model is not defined at x0, as for node_init. */
int pvtol_master_init(pvtol_master* master, const pvtol_real x0[PVTOL_NX],
                      const pvtol_real P0[PVTOL_NXX], const pvtol_real q[PVTOL_NQ]);
/**
 * Fuse the packets of step k. present[i] = 0 leaves node i out; a packet from an older step is
 * predicted to k with the stored inputs, one older than NMAX steps or from the future is ignored.
 * With no packet the estimate is the master's prediction. May be called again in the same step:
 * information adds, so a call adds the packets not yet fused to the estimate (one already fused
 * is ignored): fuse packets as they arrive.
 * A present packet whose P or P_pred is not symmetric positive definite, or (difference rule)
 * whose P exceeds P_pred on the diagonal, refuses the call (ERR_SINGULAR).
 */
int pvtol_master_fuse(pvtol_master* master, const pvtol_packet packets[PVTOL_NNODES],
                      const uint8_t present[PVTOL_NNODES]);
/** Predict to step k + 1 with the broadcast input (u), as the nodes. */
int pvtol_master_predict(pvtol_master* master, const pvtol_real input[PVTOL_NW]);
/** Fused estimate; either output may be NULL. */
int pvtol_master_estimate(const pvtol_master* master, pvtol_real x[PVTOL_NX],
                          pvtol_real P[PVTOL_NXX]);

/* ---- wire (docs/wire.md) ------------------------------------------------------------------- */
/* Fixed-size little-endian frames: a 32-byte header (magic "DFEW", version, kind, flags, bytes per
 * real, model hash prefix, node id, reals in the payload, step, sequence number, epoch), the
 * payload, a SipHash-2-4 tag (zero without a key) and a CRC-32 (IEEE, = zlib.crc32 of the bytes
 * before it). The epoch is the master's boot: its commands and announcements carry it, the
 * nodes' packets echo the last one they heard, and a keyed master takes only its own. */
#define PVTOL_WIRE_VERSION 3u
#define PVTOL_WIRE_HEADER 32u
/** bytes of a frame of n reals: header, n reals of 8 bytes, tag (8) and CRC (4) */
#define PVTOL_FRAME_SIZE(n) (44u + (8u * (size_t)(n)))
/** node -> master: a pvtol_packet */
#define PVTOL_KIND_PACKET 1u
/** master -> nodes and actuator: (k, v, u) */
#define PVTOL_KIND_COMMAND 2u
/** master -> nodes: its epoch, no reals (a master that cannot command yet: restarted) */
#define PVTOL_KIND_ANNOUNCE 5u
/** node id field of the master's frames */
#define PVTOL_MASTER_ID 0xFFFFu
/** reals in a packet (NY + 2 NX + 2 NX^2) */
#define PVTOL_PACKET_REALS 146
/** reals after v in a command: u */
#define PVTOL_NU_WIRE PVTOL_NU
/** reals in a command: v, u */
#define PVTOL_COMMAND_REALS (PVTOL_NY + PVTOL_NU_WIRE)
/** FRAME_SIZE(PACKET_REALS) */
#define PVTOL_PACKET_WIRE_SIZE 1212u
/** FRAME_SIZE(COMMAND_REALS) */
#define PVTOL_COMMAND_WIRE_SIZE 76u
/** FRAME_SIZE(0) */
#define PVTOL_ANNOUNCE_WIRE_SIZE 44u
/** frame of the wrong size */
#define PVTOL_ERR_WIRE_LENGTH (-10)
/** CRC-32 mismatch: corrupted on the way */
#define PVTOL_ERR_WIRE_CRC (-11)
/** not a frame of this kind: magic, kind, real size or count */
#define PVTOL_ERR_WIRE_FORMAT (-12)
/** another wire format version */
#define PVTOL_ERR_WIRE_VERSION (-13)
/** another model (hash prefix) */
#define PVTOL_ERR_WIRE_MODEL (-14)
/** keyed tag missing or wrong */
#define PVTOL_ERR_WIRE_TAG (-15)
/** unknown node id */
#define PVTOL_ERR_WIRE_NODE (-16)
/** that (node, step) was already received */
#define PVTOL_ERR_WIRE_DUPLICATE (-17)
/** older than the window (or than the master's start) */
#define PVTOL_ERR_WIRE_OLD (-18)
/** from a step the master has not reached */
#define PVTOL_ERR_WIRE_FUTURE (-19)
/** keyed: sequence number not above the last one */
#define PVTOL_ERR_WIRE_REPLAY (-20)
/** older than a packet already received from that node */
#define PVTOL_ERR_WIRE_OUTDATED (-21)
/** A packet's P or P_pred is not symmetric positive definite. */
#define PVTOL_ERR_WIRE_COVARIANCE (-22)
/** A packet's P exceeds its P_pred on the diagonal (difference rule: a negative gain). */
#define PVTOL_ERR_WIRE_GAIN (-23)
/** keyed: another epoch than the master's (a frame of an earlier boot, or a node not yet told) */
#define PVTOL_ERR_WIRE_EPOCH (-24)

typedef struct {
    uint8_t kind;
    uint16_t node;
    uint32_t step;
    uint32_t seq;
    uint32_t epoch;
} pvtol_frame_header;

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
} pvtol_wire_counters;

/** The master's receive side: checked packets staged for the next fuse, per-node last step and
 * sequence number, the deployment key, the master's epoch and what was rejected. `base` is the
 * global step of the master's step 0 (a restarted master starts at the step it rejoins). */
typedef struct {
    pvtol_packet staged[PVTOL_NNODES];
    uint8_t present[PVTOL_NNODES];
    uint8_t seen[PVTOL_NNODES];
    uint32_t last_step[PVTOL_NNODES];
    uint32_t last_seq[PVTOL_NNODES];
    uint32_t base;
    uint32_t epoch;
    uint32_t accepted;
    uint8_t key[16];
    uint8_t keyed;
    pvtol_wire_counters rejected;
} pvtol_inbox;

/** A node's receive side for the master's commands and announcements: the master's epoch as
 * last heard (the node's packets carry it) and the last sequence number in that epoch. */
typedef struct {
    uint32_t epoch;
    uint32_t last_seq;
    uint32_t accepted;
    uint8_t seen;
    uint8_t key[16];
    uint8_t keyed;
    pvtol_wire_counters rejected;
} pvtol_command_rx;

/** CRC-32 of len bytes (data NULL: 0, the CRC of none). */
uint32_t pvtol_crc32(const uint8_t* data, size_t len);
/** SipHash-2-4 of len bytes under key (key NULL, or data NULL with len > 0: 0). */
uint64_t pvtol_siphash24(const uint8_t key[16], const uint8_t* data, size_t len);
/** Any frame: header fields, `count` reals; key NULL = CRC only. buf holds FRAME_SIZE(count)
 * bytes. */
int pvtol_frame_encode(const pvtol_frame_header* header, const pvtol_real* values, uint16_t count,
                       const uint8_t* key, uint8_t* buf, size_t cap);
/** Checks size, CRC, magic/kind/count, version, model, tag (if key), finiteness; then fills
 * values. */
int pvtol_frame_decode(const uint8_t* buf, size_t len, const uint8_t* key, uint8_t kind,
                       pvtol_real* values, uint16_t count, pvtol_frame_header* header);
/** epoch: the master's, as the node last heard it (its command_rx's `epoch`). */
int pvtol_packet_encode(const pvtol_packet* packet, uint16_t node, uint32_t seq, uint32_t epoch,
                        const uint8_t* key, uint8_t buf[PVTOL_PACKET_WIRE_SIZE]);
int pvtol_packet_decode(const uint8_t* buf, size_t len, const uint8_t* key, pvtol_packet* packet,
                        pvtol_frame_header* header);
/** epoch: the master's (as given to inbox_init). */
int pvtol_command_encode(uint32_t step, const pvtol_real v[PVTOL_NY],
                         const pvtol_real u[PVTOL_NU_WIRE], uint32_t seq, uint32_t epoch,
                         const uint8_t* key, uint8_t buf[PVTOL_COMMAND_WIRE_SIZE]);
/** The master's epoch without a command (a restarted master, before it can command). */
int pvtol_announce_encode(uint32_t step, uint32_t seq, uint32_t epoch, const uint8_t* key,
                          uint8_t buf[PVTOL_ANNOUNCE_WIRE_SIZE]);
int pvtol_command_decode(const uint8_t* buf, size_t len, const uint8_t* key, pvtol_real v[PVTOL_NY],
                         pvtol_real u[PVTOL_NU_WIRE], pvtol_frame_header* header);
/** key NULL: CRC only; base: global step of the master's step 0; epoch: this boot's, chosen by the
 * caller and never used before under this key (a boot counter kept in non-volatile memory,
 * incremented at every boot: the nodes take a newer epoch, RFC 1982 order, and refuse older
 * ones). */
int pvtol_inbox_init(pvtol_inbox* inbox, const uint8_t key[16], uint32_t base, uint32_t epoch);
/** A restarted master's first packet: the checks of master_receive that need no master state
 * (integrity, node id, keyed: the epoch, covariances), counted per cause. OK: the
 * packet (its step global) to initialise from; stage it afterwards with master_receive. */
int pvtol_inbox_join(pvtol_inbox* inbox, const uint8_t* buf, size_t len, pvtol_packet* packet,
                     pvtol_frame_header* header);
/** Check a received frame (integrity, identity, window, duplicates, replay, then the packet's
 * covariances as master_fuse needs them) and stage it for the next fuse; a rejected frame is
 * counted per cause and changes nothing else (its node's packet for that step is still taken). */
int pvtol_master_receive(const pvtol_master* master, pvtol_inbox* inbox, const uint8_t* buf,
                         size_t len);
/** Fuse the staged packets (master_fuse), then clear them. If that fails (ERR_SINGULAR or
 * ERR_NONFINITE), the packets are added one by one in node order, each one whose addition
 * cannot be fused is dropped (counted: unfused), and the rest are fused: one bad packet costs
 * only its own node. */
int pvtol_master_fuse_inbox(pvtol_master* master, pvtol_inbox* inbox);
size_t pvtol_inbox_size(void);
size_t pvtol_command_rx_size(void);
/** The rejection counters of an inbox (or, with inbox NULL, of a command receiver). */
int pvtol_wire_rejected(const pvtol_inbox* inbox, const pvtol_command_rx* rx,
                        pvtol_wire_counters* out);
/** epoch: the latest master epoch this node has heard, kept by the caller across the node's own
 * restarts (0 if none): with a key, commands of an older epoch are refused. */
int pvtol_command_rx_init(pvtol_command_rx* rx, const uint8_t key[16], uint32_t epoch);
/** Check a command frame (integrity, from the master; keyed: an epoch not older than the last
 * one heard, a newer one taken, and within it a fresh sequence number). */
int pvtol_command_receive(pvtol_command_rx* rx, const uint8_t* buf, size_t len, uint32_t* step,
                          pvtol_real v[PVTOL_NY], pvtol_real u[PVTOL_NU_WIRE]);
/** Check an announcement (as command_receive) and take its epoch. */
int pvtol_announce_receive(pvtol_command_rx* rx, const uint8_t* buf, size_t len);

/* ---- control ---------------------------------------------------------------------------- */
/**
 * Flatness-based control: v_j = y_d^(r) - sum_i k_(r-i) e_i on each chain (heads wrapped for
 * angles), u = G(x)^-1 (v - F(x)). gains per chain [k_1 .. k_r] (see pvtol_gains).
 * v may be NULL. ERR_SINGULAR when |det G(x)| < SINGULAR_RTOL * DET_NOMINAL (G at the nominal
 * state). Declared input limits clamp u; *saturated (may be NULL) is incremented by the inputs
 * clamped.
 */
int pvtol_control(const pvtol_real x[PVTOL_NX], const pvtol_real flags[PVTOL_NFLAGS],
                  const pvtol_real gains[PVTOL_NZ], const pvtol_real params[PVTOL_NP_SLOTS],
                  pvtol_real u[PVTOL_NU], pvtol_real v[PVTOL_NY], uint32_t* saturated);
/** Gains placing all poles of chain j at -lambda[j]:
 * s^r + k_1 s^(r-1) + ... + k_r = (s + lambda)^r. A lambda[j] <= 0 (not stable) is ERR_ARG. */
int pvtol_gains(const pvtol_real lambda[PVTOL_NY], pvtol_real gains[PVTOL_NZ]);
/** The input every node_predict and master_predict of the step takes, which the master
 * broadcasts: u, from control's u and v and the
 * master's fused estimate x (master_estimate's, absolute). */
int pvtol_broadcast(const pvtol_real u[PVTOL_NU], const pvtol_real v[PVTOL_NY],
                    const pvtol_real x[PVTOL_NX], pvtol_real w[PVTOL_NW]);

/* ---- dynamic extension ------------------------------------------------------------------ */
/** The controller's integrator states (T, T_d1): the model as written
 * has a singular decoupling matrix, so pvtol_control computes the extended system's inputs
 * (T_d2, tau). Initialise xi from the last PVTOL_NXI entries of
 * Phi^-1 of the first estimate. */
#define PVTOL_NXI 2
/**
 * One period of the controller's integrators: u_plant = the input to apply now, held over the
 * period (the first state of each chain; an input without a chain passes u through), then xi
 * advanced exactly under u held: xi_a += sum_b xi_b Ts^(b-a)/(b-a)! + u Ts^(r-a)/(r-a)!.
 * On an error xi and u_plant are left alone.
 */
int pvtol_extension_step(pvtol_real xi[PVTOL_NXI], const pvtol_real u[PVTOL_NU],
                         pvtol_real u_plant[PVTOL_NU]);

#ifdef __cplusplus
}
#endif

#endif /* PVTOL_H */
