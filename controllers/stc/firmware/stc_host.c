/* The host's batch entry point (not built for a microcontroller): many independent ticks in one
 * call, so that a million (state, reading) pairs cost one call from Python.
 *   states:  3 bytes per tick (stc_state)
 *   obs:     5 bytes per tick (stc_obs)
 *   out:     8 bytes per tick: status, action, state (3), decision (3) */
#include <stdint.h>
#include "stc_fsm.h"

#define STATE_BYTES 3u
#define OBS_BYTES 5u
#define OUT_BYTES 8u

void stc_step_batch(uint32_t n, const uint8_t *states, const uint8_t *obs, uint8_t *out)
{
    uint32_t i;
    for (i = 0u; i < n; i++) {
        const uint8_t *si = states + STATE_BYTES * i, *oi = obs + OBS_BYTES * i;
        uint8_t *r = out + OUT_BYTES * i;
        stc_state s;
        stc_obs o;
        stc_decision d;
        uint8_t action = 0u, status;
        s.mode = si[0];
        s.where = si[1];
        s.flags = si[2];
        o.kind = oi[0];
        o.boxes = oi[1];
        o.neigh = oi[2];
        o.start = oi[3];
        o.landing = oi[4];
        d.flags = d.dirs = d.free = 0u;
        status = stc_step(&s, &o, &action, &d);
        r[0] = status;
        r[1] = action;
        r[2] = s.mode;
        r[3] = s.where;
        r[4] = s.flags;
        r[5] = d.flags;
        r[6] = d.dirs;
        r[7] = d.free;
    }
}

uint32_t stc_state_size(void)
{
    return (uint32_t)sizeof(stc_state);
}
