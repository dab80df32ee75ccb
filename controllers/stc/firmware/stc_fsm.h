/* The ant-like STC controller (Srour and Abboud, "Optimally Covering an Unknown Environment
 * with Ant-like STC algorithm") as portable C99: the decision and the finite-state machine's
 * step exactly as the Python module stcvision.controllers.stc.fsm defines them.
 *
 * No heap, no recursion, no floating point: every quantity is a direction, a sub-cell index or
 * a flag. One source builds for the host (cc, loaded by ctypes) and for a microcontroller.
 *
 * The byte layouts below are also the serial protocol's payloads (docs: "Serial protocol"); the
 * Python side reads the same layouts in stcvision.controllers.stc.wire, and the identity tests
 * hold the two equal on every value of every field. */
#ifndef STC_FSM_H
#define STC_FSM_H

#include <stdint.h>

/* phases: the values of the Python StcPhase */
enum {
    STC_INIT = 0, STC_START_MARK = 1, STC_START_FACE = 2, STC_DECIDE = 3,
    STC_MOVE = 4, STC_DONE = 5, STC_LOOK = 6
};
/* actions, in the order of the Python Action enum */
enum {
    STC_ACT_FORWARD = 0, STC_ACT_TURN_LEFT = 1, STC_ACT_TURN_RIGHT = 2,
    STC_ACT_MARK = 3, STC_ACT_LOOK = 4, STC_ACT_DONE = 5
};
/* what a tick reads: nothing, a cell's observation, or a look ahead */
enum { STC_OBS_NONE = 0, STC_OBS_CELL = 1, STC_OBS_LOOK = 2 };
/* a step's status: done, or why the state and the reading cannot go together (the Python step
 * raises ValueError on each; the state is then left as it was) */
enum { STC_OK = 0, STC_ERR_NEED_CELL = 1, STC_ERR_NEED_LOOK = 2, STC_ERR_STATE = 3 };

/* "no such direction / sub-cell" (a child that is none, a cell without the start mark) */
#define STC_NONE 4u

/* The controller's state, three bytes (no map, no history):
 *   mode:  bits 0-2 phase, bits 4-7 the "looked free" bit per direction
 *   where: bits 0-1 sub-cell, 2-3 heading, 4-5 target (exit direction), 6-7 parent direction
 *   flags: the STC_F_* bits */
typedef struct {
    uint8_t mode;
    uint8_t where;
    uint8_t flags;
} stc_state;

#define STC_F_FINAL 0x01u
#define STC_F_CLOSING 0x02u
#define STC_F_AT_START 0x04u
#define STC_F_IS_START 0x08u
#define STC_F_LAND_PARENT 0x10u
#define STC_F_LAND_KNOWN 0x20u
#define STC_F_CHILD 0x40u
#define STC_F_FRESH 0x80u

/* One tick's reading, five bytes:
 *   kind:    STC_OBS_*
 *   boxes:   bit b-1 = box b lit (boxes 1..5); for a look, bit 0 = the cell ahead is marked
 *   neigh:   bits 0-3 neighbour d has marks, bits 4-7 neighbour d shows a red light
 *   start:   the entry-frame sub-cell holding the start mark, STC_NONE if not this cell
 *   landing: bits 0-3 the landing sub-cell towards d is marked, bits 4-7 that is known */
typedef struct {
    uint8_t kind;
    uint8_t boxes;
    uint8_t neigh;
    uint8_t start;
    uint8_t landing;
} stc_obs;

/* A decision (made only on a DECIDE tick that read a cell), three bytes:
 *   flags: bits 0-2 sub-cells 1..3 visited, 3 is_start, 4 done, 5 final, 7 a decision was made
 *   dirs:  bits 0-1 parent, 2-3 target, 4-6 child (STC_NONE: none)
 *   free:  bits 0-3 candidate children */
typedef struct {
    uint8_t flags;
    uint8_t dirs;
    uint8_t free;
} stc_decision;

#define STC_D_IS_START 0x08u
#define STC_D_DONE 0x10u
#define STC_D_FINAL 0x20u
#define STC_D_MADE 0x80u

/* the state before the first tick */
stc_state stc_initial(void);

/* One controller tick: reads *obs, updates *state, writes the action and the decision (flags 0
 * when no decision was made). Returns STC_OK or an STC_ERR_* (then nothing is written). */
uint8_t stc_step(stc_state *state, const stc_obs *obs, uint8_t *action, stc_decision *decision);

#endif
