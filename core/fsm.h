/* SPDX-License-Identifier: MIT */
/*
 * core/fsm.h - the one state-machine shape of core/.
 *
 * A machine is a table of states indexed by the owner's enum. Each state
 * has up to five handlers; every handler but on_leave returns the next
 * state, or CO_FSM_STAY. The driver runs the enter loop: leave the old
 * state, switch, call on_enter, and follow what on_enter returns until a
 * state stays (bounded by CO_FSM_MAX_CHAIN to catch a cycle in a table).
 *
 *   on_enter(obj, now)          the state was entered: send, arm timers
 *   on_frame(obj, frame, now)   a frame for this machine arrived
 *   on_timeout(obj, now)        the machine's own timer expired
 *   on_con(obj, con, now)       a confirmation of a request this machine
 *                               made (SDO client, LSS master, a sub-machine)
 *   on_leave(obj, now)          the state is left (cancel what it owns)
 *
 * A NULL handler means "ignore, stay". The owner keeps the timer and calls
 * co_fsm_timeout when it expires; the machine knows nothing of deadlines.
 * Pure code: no I/O, time comes in as a parameter, one thread.
 */
#ifndef COGW_CORE_FSM_H
#define COGW_CORE_FSM_H

#include <stdint.h>

#include "core/frame.h"

#define CO_FSM_STAY (-1)
#define CO_FSM_MAX_CHAIN 32

typedef struct co_fsm_state {
	const char *name; /* also what <machine>_state_to_string returns */
	int (*on_enter)(void *obj, uint64_t now_us);
	int (*on_frame)(void *obj, const co_frame *f, uint64_t now_us);
	int (*on_timeout)(void *obj, uint64_t now_us);
	int (*on_con)(void *obj, const void *con, uint64_t now_us);
	void (*on_leave)(void *obj, uint64_t now_us);
} co_fsm_state;

typedef struct co_fsm_def {
	const char *name;           /* "sdo_server", for diagnostics */
	const co_fsm_state *states; /* indexed by the owner's state enum */
	int n_states;
} co_fsm_def;

typedef struct co_fsm {
	const co_fsm_def *def;
	void *obj; /* passed to every handler */
	int state; /* index into def->states */
} co_fsm;

/* Put the machine in `initial` without calling any handler. */
void co_fsm_init(co_fsm *m, const co_fsm_def *def, void *obj, int initial);
/* Leave the current state and enter `next` (and whatever its on_enter
 * chains to). Entering the current state again runs leave + enter. */
void co_fsm_goto(co_fsm *m, int next, uint64_t now_us);
/* Deliver an input to the current state; follow the state it returns. */
void co_fsm_frame(co_fsm *m, const co_frame *f, uint64_t now_us);
void co_fsm_timeout(co_fsm *m, uint64_t now_us);
void co_fsm_con(co_fsm *m, const void *con, uint64_t now_us);

static inline int co_fsm_state_of(const co_fsm *m)
{
	return m->state;
}
/* Name of a state of a table ("?" when out of range). */
const char *co_fsm_state_name(const co_fsm_def *def, int state);

#endif /* COGW_CORE_FSM_H */
