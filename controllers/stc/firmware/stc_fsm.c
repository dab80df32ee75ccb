/* The ant-like STC controller's tick in portable C99 (see stc_fsm.h). Each function mirrors
 * the Python function of the same name in stcvision.controllers.stc.fsm, line for line. */
#include "stc_fsm.h"

/* the state's fields */
#define PHASE(s) ((uint8_t)((s).mode & 7u))
#define FREE(s) ((uint8_t)((s).mode >> 4))
#define SUB(s) ((uint8_t)((s).where & 3u))
#define HEADING(s) ((uint8_t)(((s).where >> 2) & 3u))
#define TARGET(s) ((uint8_t)(((s).where >> 4) & 3u))
#define PARENT(s) ((uint8_t)((s).where >> 6))

/* the defaults of a fresh Python StcState: heading up, parent behind, landing known */
#define DEFAULT_HEADING 1u
#define DEFAULT_PARENT 3u
#define DEFAULT_FLAGS STC_F_LAND_KNOWN

/* compile-time check that the state is three bytes (C99 has no _Static_assert) */
typedef char stc_state_is_three_bytes[(sizeof(stc_state) == 3) ? 1 : -1];

static stc_state make(uint8_t phase, uint8_t sub, uint8_t heading, uint8_t target, uint8_t parent,
                      uint8_t free, uint8_t flags)
{
    stc_state s;
    s.mode = (uint8_t)((phase & 7u) | (uint8_t)((free & 15u) << 4));
    s.where = (uint8_t)((sub & 3u) | ((heading & 3u) << 2) | ((target & 3u) << 4) | ((parent & 3u) << 6));
    s.flags = flags;
    return s;
}

/* a state of this phase with every other field at its default */
static stc_state fresh_state(uint8_t phase, uint8_t flags)
{
    return make(phase, 0u, DEFAULT_HEADING, 0u, DEFAULT_PARENT, 0u, (uint8_t)(DEFAULT_FLAGS | flags));
}

static stc_state with_phase(stc_state s, uint8_t phase)
{
    s.mode = (uint8_t)((s.mode & ~7u) | phase);
    return s;
}

stc_state stc_initial(void)
{
    return fresh_state(STC_INIT, 0u);
}

/* The first free neighbour counter-clockwise from the parent (the virtual parent last in the
 * start cell), or the first after `after` in that order (STC_NONE: from the start). Writes the
 * direction or STC_NONE to *child; returns 0 when `after` is not in the order (the Python
 * list.index raises). */
static uint8_t next_child(uint8_t parent, uint8_t free, uint8_t is_start, uint8_t after, uint8_t *child)
{
    uint8_t n = is_start ? 4u : 3u;
    uint8_t k = 0u;
    if (after != STC_NONE) {
        while (k < n && ((parent + k + 1u) & 3u) != after)
            k++;
        if (k == n)
            return 0u;
        k++;
    }
    *child = STC_NONE;
    for (; k < n; k++) {
        uint8_t d = (uint8_t)((parent + k + 1u) & 3u);
        if (free >> d & 1u) {
            *child = d;
            break;
        }
    }
    return 1u;
}

/* the ant-like STC decision from one observation (pure) */
static stc_decision decide(const stc_obs *obs, uint8_t at_start)
{
    stc_decision dec;
    uint8_t b = obs->boxes;
    /* sub-cell 1 visited iff box 1 or 5, 2 iff box 2 or 3, 3 iff box 4; bit m = sub-cell m */
    uint8_t v = (uint8_t)((((b & 0x11u) != 0u) << 1) | (((b & 0x06u) != 0u) << 2) | (((b & 0x08u) != 0u) << 3));
    uint8_t is_start = (uint8_t)(obs->start != STC_NONE || at_start);
    uint8_t parent = 3u, free = 0u, child = STC_NONE, m, d;
    if (is_start && obs->start == 0u && v == 0x0Eu) {
        dec.flags = (uint8_t)(STC_D_MADE | (v >> 1) | STC_D_IS_START | STC_D_DONE | STC_D_FINAL);
        dec.dirs = (uint8_t)(3u | (0u << 2) | (STC_NONE << 4));
        dec.free = 0u;
        return dec;
    }
    for (m = 1u; m <= 3u; m++) {
        if (!(v >> (m - 1u) & 1u) && (v >> m & 1u)) {
            parent = (uint8_t)(m - 1u);
            break;
        }
    }
    /* a candidate child: no red light, no mark, its exit reached through unvisited sub-cells */
    for (d = 0u; d < 4u; d++) {
        uint8_t seen = (uint8_t)((obs->neigh >> d & 1u) | (obs->neigh >> (d + 4u) & 1u));
        uint8_t through = (uint8_t)(v & (uint8_t)((2u << d) - 2u)); /* sub-cells 1..d */
        if (!seen && !through)
            free |= (uint8_t)(1u << d);
    }
    (void)next_child(parent, free, is_start, STC_NONE, &child);
    dec.flags = (uint8_t)(STC_D_MADE | (v >> 1) | (is_start ? STC_D_IS_START : 0u));
    if (child != STC_NONE) {
        dec.dirs = (uint8_t)(parent | (child << 2) | (child << 4));
    } else {
        dec.dirs = (uint8_t)(parent | (parent << 2) | (STC_NONE << 4));
        if (is_start)
            dec.flags |= STC_D_FINAL;
    }
    dec.free = free;
    return dec;
}

/* the MOVE state towards `child`, or back to the parent when there is none */
static stc_state plan(uint8_t parent, uint8_t free, uint8_t is_start, uint8_t land_parent, uint8_t child,
                      uint8_t land_known, uint8_t sub, uint8_t heading)
{
    uint8_t target, flags = 0u;
    if (child != STC_NONE) {
        target = child;
        flags |= STC_F_CHILD;
    } else {
        target = parent;
        if (is_start)
            flags |= STC_F_FINAL;
        else if (land_parent)
            flags |= STC_F_CLOSING;
    }
    if (is_start)
        flags |= STC_F_IS_START;
    if (land_parent)
        flags |= STC_F_LAND_PARENT;
    if (land_known)
        flags |= STC_F_LAND_KNOWN;
    return make(STC_MOVE, sub, heading, target, parent, free, flags);
}

/* the MOVE phase's tick: turn towards the next sub-cell on the way to the exit (counter-
 * clockwise), drive there, look before leaving, leave, or stop in the final sub-cell */
static stc_state walk(stc_state s, uint8_t *action)
{
    uint8_t m = SUB(s), r = HEADING(s), j = TARGET(s), want, turn;
    if ((s.flags & STC_F_FINAL) && m == j) {
        *action = STC_ACT_DONE;
        return make(STC_DONE, m, r, j, DEFAULT_PARENT, 0u, (uint8_t)(DEFAULT_FLAGS | STC_F_FINAL));
    }
    want = (m == j) ? j : (uint8_t)((m + 1u) & 3u);
    if (r == want) {
        if (m == j && ((s.flags & STC_F_CHILD) || !(s.flags & (STC_F_CLOSING | STC_F_LAND_KNOWN)))) {
            /* look at the child before entering it; before a return to the parent, at the
             * sub-cell it lands on, unless the decision's frames could tell */
            *action = STC_ACT_LOOK;
            return with_phase(s, STC_LOOK);
        }
        *action = STC_ACT_FORWARD;
        if (m == j) /* leave the cell: a new entry frame in the next cell */
            return fresh_state(STC_DECIDE, (uint8_t)(s.flags & STC_F_CLOSING));
        s.where = (uint8_t)((s.where & ~3u) | ((m + 1u) & 3u));
        return s;
    }
    turn = (uint8_t)((want - r) & 3u);
    if (turn == 1u || turn == 2u) {
        *action = STC_ACT_TURN_LEFT;
        r = (uint8_t)((r + 1u) & 3u);
    } else {
        *action = STC_ACT_TURN_RIGHT;
        r = (uint8_t)((r + 3u) & 3u);
    }
    s.where = (uint8_t)((s.where & ~0x0Cu) | (r << 2));
    return s;
}

uint8_t stc_step(stc_state *state, const stc_obs *obs, uint8_t *action, stc_decision *decision)
{
    stc_state s = *state, out;
    stc_decision dec;
    uint8_t act = STC_ACT_DONE;
    dec.flags = 0u;
    dec.dirs = 0u;
    dec.free = 0u;
    switch (PHASE(s)) {
    case STC_INIT:
        out = with_phase(s, STC_START_MARK);
        act = STC_ACT_TURN_LEFT;
        break;
    case STC_START_MARK:
        out = with_phase(s, STC_START_FACE);
        act = STC_ACT_MARK;
        break;
    case STC_START_FACE:
        out = fresh_state(STC_DECIDE, STC_F_AT_START);
        act = STC_ACT_TURN_RIGHT;
        break;
    case STC_DONE:
        out = s;
        break;
    case STC_DECIDE: {
        uint8_t parent, land, known, child;
        if (s.flags & STC_F_CLOSING) { /* just drove onto the marked start sub-cell: closed */
            out = fresh_state(STC_DONE, 0u);
            break;
        }
        if (obs->kind != STC_OBS_CELL)
            return STC_ERR_NEED_CELL;
        dec = decide(obs, (uint8_t)((s.flags & STC_F_AT_START) != 0u));
        if (dec.flags & STC_D_DONE) {
            out = fresh_state(STC_DONE, 0u);
            break;
        }
        parent = (uint8_t)(dec.dirs & 3u);
        child = (uint8_t)(dec.dirs >> 4);
        land = (uint8_t)(obs->landing >> parent & 1u);
        known = (uint8_t)(land | (obs->landing >> (parent + 4u) & 1u));
        out = walk(plan(parent, dec.free, (uint8_t)((dec.flags & STC_D_IS_START) != 0u), land, child, known, 0u,
                        DEFAULT_HEADING),
                   &act);
        break;
    }
    case STC_LOOK: {
        uint8_t marked, free, nxt;
        if (obs->kind != STC_OBS_LOOK)
            return STC_ERR_NEED_LOOK;
        marked = (uint8_t)(obs->boxes & 1u);
        act = STC_ACT_FORWARD;
        if (!(s.flags & STC_F_CHILD)) { /* the look at the parent's sub-cell ahead */
            out = fresh_state(STC_DECIDE, marked ? STC_F_CLOSING : 0u);
            break;
        }
        if (!marked) { /* a new cell indeed: enter it */
            out = fresh_state(STC_DECIDE, STC_F_FRESH);
            break;
        }
        free = (uint8_t)(FREE(s) & ~(1u << TARGET(s)));
        if (!next_child(PARENT(s), free, (uint8_t)((s.flags & STC_F_IS_START) != 0u), TARGET(s), &nxt))
            return STC_ERR_STATE;
        out = walk(plan(PARENT(s), free, (uint8_t)((s.flags & STC_F_IS_START) != 0u),
                        (uint8_t)((s.flags & STC_F_LAND_PARENT) != 0u), nxt,
                        (uint8_t)((s.flags & STC_F_LAND_KNOWN) != 0u), SUB(s), HEADING(s)),
                   &act);
        break;
    }
    case STC_MOVE:
        out = walk(s, &act);
        break;
    default:
        return STC_ERR_STATE;
    }
    *state = out;
    *action = act;
    *decision = dec;
    return STC_OK;
}
