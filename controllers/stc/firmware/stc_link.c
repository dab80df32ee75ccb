/* The serial protocol's controller side (see stc_link.h): a byte-at-a-time frame reader, the
 * checksum, and the answers to HELLO, STEP, STEP_FROM, RESET and STATS. */
#include "stc_link.h"
#include "stc_fsm.h"

/* the frame reader's position: waiting for the sync byte, then the header, payload, checksum */
enum { AT_SYNC, AT_VERSION, AT_TYPE, AT_SEQ, AT_LENGTH, AT_PAYLOAD, AT_CRC_HI, AT_CRC_LO };

#define HELLO_NAME "stc firmware"
#define STATE_BYTES 3u
#define OBS_BYTES 5u

static struct {
    uint8_t at, version, type, seq, length, got;
    uint16_t crc, sent_crc;
    uint8_t payload[STC_LINK_MAX_PAYLOAD];
} rx;

static stc_state held; /* the controller's state, kept between STEP requests */

/* CRC-16/CCITT-FALSE, one byte at a time (polynomial 0x1021) */
static uint16_t crc_byte(uint16_t crc, uint8_t byte)
{
    uint8_t i;
    crc ^= (uint16_t)((uint16_t)byte << 8);
    for (i = 0u; i < 8u; i++)
        crc = (uint16_t)((crc & 0x8000u) ? (uint16_t)((crc << 1) ^ 0x1021u) : (uint16_t)(crc << 1));
    return crc;
}

static void send(uint8_t type, uint8_t seq, const uint8_t *payload, uint8_t n)
{
    uint8_t head[4], i;
    uint16_t crc = 0xFFFFu;
    head[0] = STC_LINK_VERSION;
    head[1] = type;
    head[2] = seq;
    head[3] = n;
    stc_platform_put(STC_LINK_SYNC);
    for (i = 0u; i < 4u; i++) {
        crc = crc_byte(crc, head[i]);
        stc_platform_put(head[i]);
    }
    for (i = 0u; i < n; i++) {
        crc = crc_byte(crc, payload[i]);
        stc_platform_put(payload[i]);
    }
    stc_platform_put((uint8_t)(crc >> 8));
    stc_platform_put((uint8_t)(crc & 0xFFu));
}

static void nak(uint8_t seq, uint8_t code)
{
    send(STC_LINK_NAK, seq, &code, 1u);
}

/* a STEP or STEP_FROM: the tick's status, action, state and decision */
static void step_reply(uint8_t seq, uint8_t type, stc_state *s, const uint8_t *o)
{
    uint8_t out[8], action = 0u, status;
    stc_obs obs;
    stc_decision d;
    d.flags = d.dirs = d.free = 0u;
    obs.kind = o[0];
    obs.boxes = o[1];
    obs.neigh = o[2];
    obs.start = o[3];
    obs.landing = o[4];
    status = stc_step(s, &obs, &action, &d);
    out[0] = status;
    out[1] = status ? 0u : action;
    out[2] = s->mode;
    out[3] = s->where;
    out[4] = s->flags;
    out[5] = d.flags;
    out[6] = d.dirs;
    out[7] = d.free;
    send((uint8_t)(type | STC_LINK_REPLY), seq, out, 8u);
}

static void answer(void)
{
    uint8_t t = rx.type, n = rx.length, out[2 + sizeof(HELLO_NAME)], i;
    if (t == STC_REQ_HELLO && n == 0u) {
        out[0] = STC_LINK_VERSION;
        out[1] = (uint8_t)sizeof(stc_state);
        for (i = 0u; i < sizeof(HELLO_NAME) - 1u; i++)
            out[2u + i] = (uint8_t)HELLO_NAME[i];
        send(t | STC_LINK_REPLY, rx.seq, out, (uint8_t)(sizeof(HELLO_NAME) + 1u));
    } else if (t == STC_REQ_STEP && n == OBS_BYTES) {
        step_reply(rx.seq, t, &held, rx.payload);
    } else if (t == STC_REQ_STEP_FROM && n == STATE_BYTES + OBS_BYTES) {
        stc_state s;
        s.mode = rx.payload[0];
        s.where = rx.payload[1];
        s.flags = rx.payload[2];
        step_reply(rx.seq, t, &s, rx.payload + STATE_BYTES);
        held = s;
    } else if (t == STC_REQ_RESET && n == 0u) {
        held = stc_initial();
        out[0] = held.mode;
        out[1] = held.where;
        out[2] = held.flags;
        send(t | STC_LINK_REPLY, rx.seq, out, (uint8_t)STATE_BYTES);
    } else if (t == STC_REQ_STATS && n == 0u) {
        uint16_t stack = stc_platform_stack_bytes();
        out[0] = (uint8_t)(stack >> 8);
        out[1] = (uint8_t)(stack & 0xFFu);
        send(t | STC_LINK_REPLY, rx.seq, out, 2u);
    } else if (t == STC_REQ_HELLO || t == STC_REQ_STEP || t == STC_REQ_STEP_FROM || t == STC_REQ_RESET ||
               t == STC_REQ_STATS) {
        nak(rx.seq, STC_NAK_LENGTH);
    } else {
        nak(rx.seq, STC_NAK_UNKNOWN);
    }
}

void stc_link_init(void)
{
    rx.at = AT_SYNC;
    held = stc_initial();
}

void stc_link_feed(uint8_t byte)
{
    switch (rx.at) {
    case AT_SYNC:
        if (byte == STC_LINK_SYNC) {
            rx.at = AT_VERSION;
            rx.crc = 0xFFFFu;
        }
        return;
    case AT_VERSION:
        rx.version = byte;
        rx.at = AT_TYPE;
        break;
    case AT_TYPE:
        rx.type = byte;
        rx.at = AT_SEQ;
        break;
    case AT_SEQ:
        rx.seq = byte;
        rx.at = AT_LENGTH;
        break;
    case AT_LENGTH:
        rx.length = byte;
        rx.got = 0u;
        if (byte > STC_LINK_MAX_PAYLOAD) { /* no such frame: wait for the next sync byte */
            nak(rx.seq, STC_NAK_LENGTH);
            rx.at = AT_SYNC;
            return;
        }
        rx.at = byte ? AT_PAYLOAD : AT_CRC_HI;
        break;
    case AT_PAYLOAD:
        rx.payload[rx.got++] = byte;
        if (rx.got == rx.length)
            rx.at = AT_CRC_HI;
        break;
    case AT_CRC_HI:
        rx.sent_crc = (uint16_t)((uint16_t)byte << 8);
        rx.at = AT_CRC_LO;
        return;
    default: /* AT_CRC_LO: the frame is whole */
        rx.sent_crc |= byte;
        rx.at = AT_SYNC;
        if (rx.sent_crc != rx.crc)
            nak(rx.seq, STC_NAK_CHECKSUM);
        else if (rx.version != STC_LINK_VERSION)
            nak(rx.seq, STC_NAK_VERSION);
        else
            answer();
        return;
    }
    rx.crc = crc_byte(rx.crc, byte);
}
