/* DO NOT EDIT: pvtol module, generated from template wire.c.j2 by dfeif-codegen 0.1.0;
 * regenerate with `codegen build pvtol`. */
/* The wire: fixed-size little-endian frames with identity, integrity and an optional keyed tag,
 * and the master's checked receive path. Byte order and float layout are fixed here with shifts
 * of the IEEE-754 bit pattern (copied with memcpy, no type punning), so a big-endian node and a
 * little-endian master agree. Layout (docs/wire.md):
 *   0 magic "DFEW" | 4 version | 5 kind | 6 flags (bit 0 keyed) | 7 bytes per real
 *   8 model hash prefix (8 bytes) | 16 node id u16 | 18 reals in the payload u16
 *   20 step u32 | 24 sequence number u32 | 28 epoch u32 | 32 payload (reals)
 *   then a SipHash-2-4 tag (8 bytes, zero without a key) over everything before it,
 *   then CRC-32 (IEEE, reflected 0xEDB88320, = zlib.crc32) over everything before it. */
#include <string.h>
#include "pvtol_internal.h"

#define NX PVTOL_NX
#define NY PVTOL_NY
#define NXX PVTOL_NXX
#define NNODES PVTOL_NNODES
#define NMAX PVTOL_NMAX
#define HDR PVTOL_WIRE_HEADER
#define RS ((size_t)sizeof(real))
#define PACKET_REALS PVTOL_PACKET_REALS
#define PACKET_SIZE PVTOL_PACKET_WIRE_SIZE
#define COMMAND_REALS PVTOL_COMMAND_REALS
#define COMMAND_SIZE PVTOL_COMMAND_WIRE_SIZE
#define ANNOUNCE_SIZE PVTOL_ANNOUNCE_WIRE_SIZE

/* The model's SHA-256 (hex), and its first 8 bytes: the frames' model field. */
const char pvtol_model_hash[65] = PVTOL_MODEL_HASH;
/* The frames' magic, "DFEW" in ASCII. */
static const uint8_t wire_magic[4] = {0x44u, 0x46u, 0x45u, 0x57u};
static const uint8_t wire_model[8] = {0x2du, 0x79u, 0x92u, 0x98u, 0x00u, 0xdcu, 0x1fu, 0xc3u};

uint32_t pvtol_crc32(const uint8_t* data, size_t len)
{
    /* CRC-32 nibble table for the reflected polynomial 0xEDB88320. */
    static const uint32_t crc_nibble[16] = {0x00000000u, 0x1DB71064u, 0x3B6E20C8u, 0x26D930ACu,
                                            0x76DC4190u, 0x6B6B51F4u, 0x4DB26158u, 0x5005713Cu,
                                            0xEDB88320u, 0xF00F9344u, 0xD6D6A3E8u, 0xCB61B38Cu,
                                            0x9B64C2B0u, 0x86D3D2D4u, 0xA00AE278u, 0xBDBDF21Cu};
    uint32_t c = 0xFFFFFFFFu;
    size_t i;
    size_t n = (data != NULL) ? len : 0u; /* NULL: the CRC of no bytes, 0 */
    for (i = 0; i < n; i++) {
        c ^= data[i];
        c = (c >> 4) ^ crc_nibble[c & 15u];
        c = (c >> 4) ^ crc_nibble[c & 15u];
    }
    return c ^ 0xFFFFFFFFu;
}

static uint64_t get64(const uint8_t* b)
{
    uint64_t v = 0;
    int i;
    for (i = 7; i >= 0; i--) {
        v = (v << 8) | b[i];
    }
    return v;
}

static void put64(uint8_t* b, uint64_t v)
{
    uint64_t rest = v;
    int i;
    for (i = 0; i < 8; i++) {
        b[i] = (uint8_t)(rest & 0xFFu);
        rest >>= 8u;
    }
}

static uint32_t get32(const uint8_t* b)
{
    return (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) | ((uint32_t)b[3] << 24);
}

static void put32(uint8_t* b, uint32_t v)
{
    b[0] = (uint8_t)v;
    b[1] = (uint8_t)(v >> 8);
    b[2] = (uint8_t)(v >> 16);
    b[3] = (uint8_t)(v >> 24);
}

static uint16_t get16(const uint8_t* b)
{
    return (uint16_t)(b[0] | (b[1] << 8));
}

static void put16(uint8_t* b, uint16_t v)
{
    b[0] = (uint8_t)v;
    b[1] = (uint8_t)(v >> 8);
}

#define ROTL(x, b) (uint64_t)(((x) << (b)) | ((x) >> (64u - (b))))

static void sip_round(uint64_t v[4])
{
    v[0] += v[1];
    v[1] = ROTL(v[1], 13u);
    v[1] ^= v[0];
    v[0] = ROTL(v[0], 32u);
    v[2] += v[3];
    v[3] = ROTL(v[3], 16u);
    v[3] ^= v[2];
    v[0] += v[3];
    v[3] = ROTL(v[3], 21u);
    v[3] ^= v[0];
    v[2] += v[1];
    v[1] = ROTL(v[1], 17u);
    v[1] ^= v[2];
    v[2] = ROTL(v[2], 32u);
}

/* The tag itself; key and data are not NULL. */
static uint64_t siphash24(const uint8_t key[16], const uint8_t* data, size_t len)
{
    uint64_t k0 = get64(key);
    uint64_t k1 = get64(&key[8]);
    uint64_t m;
    uint64_t v[4];
    uint8_t last[8];
    size_t i;
    size_t full = len - (len % 8u);
    v[0] = k0 ^ 0x736f6d6570736575u;
    v[1] = k1 ^ 0x646f72616e646f6du;
    v[2] = k0 ^ 0x6c7967656e657261u;
    v[3] = k1 ^ 0x7465646279746573u;
    for (i = 0; i <= full; i += 8u) {
        if (i == full) { /* the last block: remaining bytes, then the length in the top byte */
            (void)memset(last, 0, sizeof(last));
            if (len > full) {
                (void)memcpy(last, &data[i], len - full);
            }
            last[7] = (uint8_t)len;
            m = get64(last);
        } else {
            m = get64(&data[i]);
        }
        v[3] ^= m;
        sip_round(v);
        sip_round(v);
        v[0] ^= m;
    }
    v[2] ^= 0xffu;
    sip_round(v);
    sip_round(v);
    sip_round(v);
    sip_round(v);
    return v[0] ^ v[1] ^ v[2] ^ v[3];
}

uint64_t pvtol_siphash24(const uint8_t key[16], const uint8_t* data, size_t len)
{
    uint64_t tag = 0u; /* no key, or no data for a nonzero length: 0 */
    if ((key != NULL) && ((data != NULL) || (len == 0u))) {
        tag = siphash24(key, (data != NULL) ? data : key, len);
    }
    return tag;
}

/* A real's bit pattern through character pointers (as memcpy would copy it, with no type
 * punning and no pointers of unrelated object types to one another). */
static uint64_t bits_of(real x)
{
    uint64_t bits = 0u;
    const uint8_t* from = (const uint8_t*)&x;
    uint8_t* to = (uint8_t*)&bits;
    size_t i;
    for (i = 0; i < sizeof(bits); i++) {
        to[i] = from[i];
    }
    return bits;
}

static real real_of(uint64_t bits)
{
    real x = (real)0;
    const uint8_t* from = (const uint8_t*)&bits;
    uint8_t* to = (uint8_t*)&x;
    size_t i;
    for (i = 0; i < sizeof(x); i++) {
        to[i] = from[i];
    }
    return x;
}

static void put_real(uint8_t* b, real x)
{
    put64(b, bits_of(x));
}

static real get_real(const uint8_t* b)
{
    return real_of(get64(b));
}

int pvtol_frame_encode(const pvtol_frame_header* header, const real* values, uint16_t count,
                       const uint8_t* key, uint8_t* buf, size_t cap)
{
    size_t i;
    size_t body = HDR + (RS * count);
    int rc = PVTOL_OK;
    if ((header == NULL) || ((count > 0u) && (values == NULL)) || (buf == NULL) ||
        (cap < PVTOL_FRAME_SIZE(count))) {
        rc = PVTOL_ERR_ARG;
    } else {
        (void)memcpy(buf, wire_magic, 4);
        buf[4] = PVTOL_WIRE_VERSION;
        buf[5] = header->kind;
        buf[6] = (uint8_t)((key != NULL) ? 1u : 0u);
        buf[7] = (uint8_t)RS;
        (void)memcpy(&buf[8], wire_model, 8);
        put16(&buf[16], header->node);
        put16(&buf[18], count);
        put32(&buf[20], header->step);
        put32(&buf[24], header->seq);
        put32(&buf[28], header->epoch);
        for (i = 0; i < count; i++) {
            put_real(&buf[HDR + (RS * i)], values[i]);
        }
        put64(&buf[body], (key != NULL) ? pvtol_siphash24(key, buf, body) : 0u);
        put32(&buf[body + 8u], pvtol_crc32(buf, body + 8u));
    }
    return rc;
}

/* The frame checks in order: size, CRC, format, version, model, tag; OK or the first failure. */
static int frame_check(const uint8_t* buf, size_t len, const uint8_t* key, uint8_t kind,
                       uint16_t count)
{
    size_t body = HDR + (RS * count);
    int rc = PVTOL_OK;
    if (len != PVTOL_FRAME_SIZE(count)) {
        rc = PVTOL_ERR_WIRE_LENGTH;
    } else if (pvtol_crc32(buf, body + 8u) != get32(&buf[body + 8u])) {
        rc = PVTOL_ERR_WIRE_CRC;
    } else if ((memcmp(buf, wire_magic, 4) != 0) || (buf[5] != kind) || (buf[7] != RS) ||
               (get16(&buf[18]) != count) || ((buf[6] & ~1u) != 0u) ||
               (((buf[6] & 1u) == 0u) && (get64(&buf[body]) != 0u))) {
        rc = PVTOL_ERR_WIRE_FORMAT; /* (untagged: the tag field must be zero) */
    } else if (buf[4] != PVTOL_WIRE_VERSION) {
        rc = PVTOL_ERR_WIRE_VERSION;
    } else if (memcmp(&buf[8], wire_model, 8) != 0) {
        rc = PVTOL_ERR_WIRE_MODEL;
    } else if ((key != NULL) && ((buf[6] & 1u) == 0u)) {
        rc = PVTOL_ERR_WIRE_TAG; /* keyed receiver, untagged frame */
    } else if ((key != NULL) && (pvtol_siphash24(key, buf, body) != get64(&buf[body]))) {
        rc = PVTOL_ERR_WIRE_TAG;
    } else {
        rc = PVTOL_OK;
    }
    return rc;
}

int pvtol_frame_decode(const uint8_t* buf, size_t len, const uint8_t* key, uint8_t kind,
                       real* values, uint16_t count, pvtol_frame_header* header)
{
    size_t i;
    int rc = PVTOL_OK;
    if ((buf == NULL) || ((count > 0u) && (values == NULL)) || (header == NULL)) {
        rc = PVTOL_ERR_ARG;
    } else {
        rc = frame_check(buf, len, key, kind, count);
    }
    for (i = 0; (i < count) && (rc == PVTOL_OK); i++) {
        real x = get_real(&buf[HDR + (RS * i)]);
        if (!pvtol_finite(&x, 1)) {
            rc = PVTOL_ERR_NONFINITE;
        }
    }
    if (rc == PVTOL_OK) {
        for (i = 0; i < count; i++) {
            values[i] = get_real(&buf[HDR + (RS * i)]);
        }
        header->kind = kind;
        header->node = get16(&buf[16]);
        header->step = get32(&buf[20]);
        header->seq = get32(&buf[24]);
        header->epoch = get32(&buf[28]);
    }
    return rc;
}

/* The packet's reals in wire order: centre, x, P, x_pred, P_pred. */
int pvtol_packet_encode(const pvtol_packet* packet, uint16_t node, uint32_t seq, uint32_t epoch,
                        const uint8_t* key, uint8_t buf[PVTOL_PACKET_WIRE_SIZE])
{
    real values[PVTOL_PACKET_REALS];
    pvtol_frame_header h;
    int rc = PVTOL_ERR_ARG;
    if (packet != NULL) {
        (void)memcpy(values, packet->centre, sizeof(packet->centre));
        (void)memcpy(&values[NY], packet->x, sizeof(packet->x));
        (void)memcpy(&values[NY + NX], packet->P, sizeof(packet->P));
        (void)memcpy(&values[NY + NX + NXX], packet->x_pred, sizeof(packet->x_pred));
        (void)memcpy(&values[NY + (2 * NX) + NXX], packet->P_pred, sizeof(packet->P_pred));
        h.kind = PVTOL_KIND_PACKET;
        h.node = node;
        h.step = packet->step;
        h.seq = seq;
        h.epoch = epoch;
        rc = pvtol_frame_encode(&h, values, PACKET_REALS, key, buf, PACKET_SIZE);
    }
    return rc;
}

static int packet_decode(const uint8_t* buf, size_t len, const uint8_t* key, pvtol_packet* packet,
                         pvtol_frame_header* header)
{
    real values[PVTOL_PACKET_REALS];
    int rc = PVTOL_ERR_ARG;
    if (packet != NULL) {
        rc = pvtol_frame_decode(buf, len, key, PVTOL_KIND_PACKET, values, PVTOL_PACKET_REALS,
                                header);
    }
    if (rc == PVTOL_OK) {
        packet->step = header->step;
        (void)memcpy(packet->centre, values, sizeof(packet->centre));
        (void)memcpy(packet->x, &values[NY], sizeof(packet->x));
        (void)memcpy(packet->P, &values[NY + NX], sizeof(packet->P));
        (void)memcpy(packet->x_pred, &values[NY + NX + NXX], sizeof(packet->x_pred));
        (void)memcpy(packet->P_pred, &values[NY + (2 * NX) + NXX], sizeof(packet->P_pred));
    }
    return rc;
}

int pvtol_packet_decode(const uint8_t* buf, size_t len, const uint8_t* key, pvtol_packet* packet,
                        pvtol_frame_header* header)
{
    return packet_decode(buf, len, key, packet, header);
}

int pvtol_command_encode(uint32_t step, const real v[NY], const real u[PVTOL_NU_WIRE], uint32_t seq,
                         uint32_t epoch, const uint8_t* key, uint8_t buf[PVTOL_COMMAND_WIRE_SIZE])
{
    real values[PVTOL_COMMAND_REALS];
    pvtol_frame_header h;
    int rc = PVTOL_ERR_ARG;
    if ((v != NULL) && (u != NULL)) {
        (void)memcpy(values, v, sizeof(real) * (size_t)NY);
        (void)memcpy(&values[NY], u, sizeof(real) * (size_t)PVTOL_NU_WIRE);
        h.kind = PVTOL_KIND_COMMAND;
        h.node = PVTOL_MASTER_ID;
        h.step = step;
        h.seq = seq;
        h.epoch = epoch;
        rc = pvtol_frame_encode(&h, values, COMMAND_REALS, key, buf, COMMAND_SIZE);
    }
    return rc;
}

int pvtol_announce_encode(uint32_t step, uint32_t seq, uint32_t epoch, const uint8_t* key,
                          uint8_t buf[PVTOL_ANNOUNCE_WIRE_SIZE])
{
    pvtol_frame_header h;
    h.kind = PVTOL_KIND_ANNOUNCE;
    h.node = PVTOL_MASTER_ID;
    h.step = step;
    h.seq = seq;
    h.epoch = epoch;
    return pvtol_frame_encode(&h, NULL, 0u, key, buf, ANNOUNCE_SIZE);
}

static int command_decode(const uint8_t* buf, size_t len, const uint8_t* key, real v[NY],
                          real u[PVTOL_NU_WIRE], pvtol_frame_header* header)
{
    real values[PVTOL_COMMAND_REALS];
    int rc = PVTOL_ERR_ARG;
    if ((v != NULL) && (u != NULL)) {
        rc = pvtol_frame_decode(buf, len, key, PVTOL_KIND_COMMAND, values, PVTOL_COMMAND_REALS,
                                header);
    }
    if (rc == PVTOL_OK) {
        (void)memcpy(v, values, sizeof(real) * (size_t)NY);
        (void)memcpy(u, &values[NY], sizeof(real) * (size_t)PVTOL_NU_WIRE);
    }
    return rc;
}

int pvtol_command_decode(const uint8_t* buf, size_t len, const uint8_t* key, real v[NY],
                         real u[PVTOL_NU_WIRE], pvtol_frame_header* header)
{
    return command_decode(buf, len, key, v, u, header);
}

/* ---- checked receive paths ------------------------------------------------------------------ */

size_t pvtol_inbox_size(void)
{
    return sizeof(pvtol_inbox);
}

size_t pvtol_command_rx_size(void)
{
    return sizeof(pvtol_command_rx);
}

int pvtol_wire_rejected(const pvtol_inbox* inbox, const pvtol_command_rx* rx,
                        pvtol_wire_counters* out)
{
    int rc = PVTOL_ERR_ARG;
    if (((inbox != NULL) || (rx != NULL)) && (out != NULL)) {
        *out = (inbox != NULL) ? inbox->rejected : rx->rejected;
        rc = PVTOL_OK;
    }
    return rc;
}

static void count_reject(pvtol_wire_counters* c, int rc)
{
    switch (rc) {
    case PVTOL_ERR_WIRE_LENGTH:
        c->length++;
        break;
    case PVTOL_ERR_WIRE_CRC:
        c->crc++;
        break;
    case PVTOL_ERR_WIRE_FORMAT:
        c->format++;
        break;
    case PVTOL_ERR_WIRE_VERSION:
        c->version++;
        break;
    case PVTOL_ERR_WIRE_MODEL:
        c->model++;
        break;
    case PVTOL_ERR_WIRE_TAG:
        c->tag++;
        break;
    case PVTOL_ERR_WIRE_NODE:
        c->node++;
        break;
    case PVTOL_ERR_WIRE_DUPLICATE:
        c->duplicate++;
        break;
    case PVTOL_ERR_WIRE_OLD:
        c->old++;
        break;
    case PVTOL_ERR_WIRE_FUTURE:
        c->future++;
        break;
    case PVTOL_ERR_WIRE_REPLAY:
        c->replay++;
        break;
    case PVTOL_ERR_WIRE_OUTDATED:
        c->outdated++;
        break;
    case PVTOL_ERR_NONFINITE:
        c->nonfinite++;
        break;
    case PVTOL_ERR_WIRE_COVARIANCE:
        c->covariance++;
        break;
    case PVTOL_ERR_WIRE_GAIN:
        c->gain++;
        break;
    case PVTOL_ERR_WIRE_EPOCH:
        c->epoch++;
        break;
    default:
        c->other++;
        break;
    }
}

int pvtol_inbox_init(pvtol_inbox* inbox, const uint8_t key[16], uint32_t base, uint32_t epoch)
{
    int rc = PVTOL_ERR_ARG;
    if (inbox != NULL) {
        (void)memset(inbox, 0, sizeof(*inbox));
        if (key != NULL) {
            (void)memcpy(inbox->key, key, sizeof(inbox->key));
            inbox->keyed = 1;
        }
        inbox->base = base;
        inbox->epoch = epoch;
        rc = PVTOL_OK;
    }
    return rc;
}

/* A keyed sequence number newer than the last accepted one, in serial-number arithmetic
 * (RFC 1982): up to 2^31 - 1 ahead, so that 0xFFFFFFFF is followed by 0 and locks no one out. */
static int seq_fresh(uint32_t seq, uint32_t last)
{
    uint32_t ahead = seq - last;
    return ((ahead != 0u) && (ahead < 0x80000000u)) ? 1 : 0;
}

/* 1 if step a comes after step b in serial-number arithmetic (steps wrap at 2^32 like the
 * sequence numbers: up to 2^31 - 1 ahead). */
static int serial_after(uint32_t a, uint32_t b)
{
    return seq_fresh(a, b);
}

/* The checks that need no master state: integrity, node id, and with a key the master's epoch
 * (a frame of an earlier boot is refused: replay protection across restarts) and a fresh
 * sequence number within it. */
static int check_origin(const pvtol_inbox* inbox, const uint8_t* buf, size_t len, pvtol_packet* pk,
                        pvtol_frame_header* h)
{
    const uint8_t* key = (inbox->keyed != 0u) ? inbox->key : NULL;
    int rc = packet_decode(buf, len, key, pk, h);
    if (rc == PVTOL_OK) {
        if (h->node >= (uint16_t)NNODES) {
            rc = PVTOL_ERR_WIRE_NODE;
        } else if ((inbox->keyed != 0u) && (h->epoch != inbox->epoch)) {
            rc = PVTOL_ERR_WIRE_EPOCH;
        } else if ((inbox->keyed != 0u) && (inbox->seen[h->node] != 0u) &&
                   (seq_fresh(h->seq, inbox->last_seq[h->node]) == 0)) {
            rc = PVTOL_ERR_WIRE_REPLAY;
        } else {
            rc = PVTOL_OK;
        }
    }
    return rc;
}

static int check_packet(const pvtol_master* master, const pvtol_inbox* inbox, const uint8_t* buf,
                        size_t len, pvtol_packet* pk, pvtol_frame_header* h)
{
    uint32_t now = inbox->base + master->k;
    int rc = check_origin(inbox, buf, len, pk, h);
    if (rc == PVTOL_OK) {
        if (serial_after(h->step, now) != 0) {
            rc = PVTOL_ERR_WIRE_FUTURE;
        } else if ((now - h->step) > master->age) { /* older than NMAX or the master's step 0 */
            rc = PVTOL_ERR_WIRE_OLD;
        } else if ((inbox->seen[h->node] != 0u) && (h->step == inbox->last_step[h->node])) {
            rc = PVTOL_ERR_WIRE_DUPLICATE;
        } else if ((inbox->seen[h->node] != 0u) &&
                   (serial_after(inbox->last_step[h->node], h->step) != 0)) {
            rc = PVTOL_ERR_WIRE_OUTDATED;
        } else {
            /* last: a packet refused here leaves its node's step open for the real one */
            rc = pvtol_packet_check(pk);
        }
    }
    return rc;
}

int pvtol_inbox_join(pvtol_inbox* inbox, const uint8_t* buf, size_t len, pvtol_packet* packet,
                     pvtol_frame_header* header)
{
    pvtol_packet pk;
    pvtol_frame_header h;
    int rc = PVTOL_ERR_ARG;
    if ((inbox != NULL) && (buf != NULL) && (packet != NULL) && (header != NULL)) {
        rc = check_origin(inbox, buf, len, &pk, &h);
        if (rc == PVTOL_OK) {
            rc = pvtol_packet_check(&pk);
        }
        if (rc != PVTOL_OK) {
            count_reject(&inbox->rejected, rc);
        } else {
            *packet = pk;
            *header = h;
        }
    }
    return rc;
}

int pvtol_master_receive(const pvtol_master* master, pvtol_inbox* inbox, const uint8_t* buf,
                         size_t len)
{
    pvtol_packet pk;
    pvtol_frame_header h;
    int rc = PVTOL_ERR_ARG;
    if ((master != NULL) && (inbox != NULL) && (buf != NULL)) {
        rc = check_packet(master, inbox, buf, len, &pk, &h);
        if (rc != PVTOL_OK) {
            count_reject(&inbox->rejected, rc);
        } else {
            pk.step = h.step - inbox->base; /* the master's own step count */
            inbox->staged[h.node] = pk;
            inbox->present[h.node] = 1;
            inbox->seen[h.node] = 1;
            inbox->last_step[h.node] = h.step;
            inbox->last_seq[h.node] = h.seq;
            inbox->accepted++;
        }
    }
    return rc;
}

/* After a failed fuse: the staged packets are taken one by one in node order, and one whose
 * addition the master cannot fuse is dropped and counted (unfused). What is left fuses (it is
 * the last set tried, or none), so one bad packet costs only its own node. */
static void drop_unfusable(pvtol_master* master, pvtol_inbox* inbox)
{
    uint8_t keep[NNODES];
    int i;
    (void)memset(keep, 0, sizeof(keep));
    for (i = 0; i < NNODES; i++) {
        if (inbox->present[i] != 0u) {
            int rc;
            keep[i] = 1u;
            rc = pvtol_master_fuse_try(master, inbox->staged, keep, 0);
            if (rc != PVTOL_OK) {
                keep[i] = 0u;
                inbox->present[i] = 0u;
                inbox->rejected.unfused++;
            }
        }
    }
}

int pvtol_master_fuse_inbox(pvtol_master* master, pvtol_inbox* inbox)
{
    int rc = PVTOL_ERR_ARG;
    if ((master != NULL) && (inbox != NULL)) {
        rc = pvtol_master_fuse(master, inbox->staged, inbox->present);
        if ((rc == PVTOL_ERR_SINGULAR) || (rc == PVTOL_ERR_NONFINITE)) {
            drop_unfusable(master, inbox);
            rc = pvtol_master_fuse(master, inbox->staged, inbox->present);
        }
        if (rc == PVTOL_OK) {
            (void)memset(inbox->present, 0, sizeof(inbox->present));
        }
    }
    return rc;
}

int pvtol_command_rx_init(pvtol_command_rx* rx, const uint8_t key[16], uint32_t epoch)
{
    int rc = PVTOL_ERR_ARG;
    if (rx != NULL) {
        (void)memset(rx, 0, sizeof(*rx));
        if (key != NULL) {
            (void)memcpy(rx->key, key, sizeof(rx->key));
            rx->keyed = 1;
        }
        rx->epoch = epoch;
        rc = PVTOL_OK;
    }
    return rc;
}

/* A master frame's origin and freshness (keyed): an epoch older than the last one heard (RFC 1982
 * order) is refused, a newer one is taken (the master restarted), and within an epoch the sequence
 * number must be fresh. Taken frames set the node's epoch: its packets carry it. */
static int master_frame_taken(pvtol_command_rx* rx, int decoded, const pvtol_frame_header* h)
{
    int rc = decoded;
    if ((rc == PVTOL_OK) && (h->node != PVTOL_MASTER_ID)) {
        rc = PVTOL_ERR_WIRE_NODE;
    }
    if ((rc == PVTOL_OK) && (rx->keyed != 0u)) {
        uint32_t ahead = h->epoch - rx->epoch; /* (decoded: h is filled) */
        if (ahead >= 0x80000000u) {
            rc = PVTOL_ERR_WIRE_EPOCH;
        } else if ((ahead == 0u) && (rx->seen != 0u) && (seq_fresh(h->seq, rx->last_seq) == 0)) {
            rc = PVTOL_ERR_WIRE_REPLAY;
        } else {
            rc = PVTOL_OK;
        }
    }
    if (rc != PVTOL_OK) {
        count_reject(&rx->rejected, rc);
    } else {
        rx->epoch = h->epoch;
        rx->seen = 1;
        rx->last_seq = h->seq;
        rx->accepted++;
    }
    return rc;
}

int pvtol_command_receive(pvtol_command_rx* rx, const uint8_t* buf, size_t len, uint32_t* step,
                          real v[NY], real u[PVTOL_NU_WIRE])
{
    pvtol_frame_header h;
    real v1[NY];
    real u1[PVTOL_NU_WIRE];
    int rc = PVTOL_ERR_ARG;
    if ((rx != NULL) && (buf != NULL) && (step != NULL) && (v != NULL) && (u != NULL)) {
        /* v1, u1 are set by a decode that succeeds; compilers cannot tell */
        (void)memset(v1, 0, sizeof(v1));
        (void)memset(u1, 0, sizeof(u1));
        rc = command_decode(buf, len, (rx->keyed != 0u) ? rx->key : NULL, v1, u1, &h);
        rc = master_frame_taken(rx, rc, &h);
        if (rc == PVTOL_OK) {
            *step = h.step;
            (void)memcpy(v, v1, sizeof(v1));
            (void)memcpy(u, u1, sizeof(u1));
        }
    }
    return rc;
}

int pvtol_announce_receive(pvtol_command_rx* rx, const uint8_t* buf, size_t len)
{
    pvtol_frame_header h;
    int rc = PVTOL_ERR_ARG;
    if ((rx != NULL) && (buf != NULL)) {
        rc = pvtol_frame_decode(buf, len, (rx->keyed != 0u) ? rx->key : NULL, PVTOL_KIND_ANNOUNCE,
                                NULL, 0u, &h);
        rc = master_frame_taken(rx, rc, &h);
    }
    return rc;
}
