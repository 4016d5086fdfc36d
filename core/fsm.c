/* SPDX-License-Identifier: MIT */
/*
 * core/fsm.c - the driver of the state-machine shape (core/fsm.h).
 */
#include "core/fsm.h"

#include <assert.h>
#include <stddef.h>

void co_fsm_init(co_fsm *m, const co_fsm_def *def, void *obj, int initial)
{
	assert(def && initial >= 0 && initial < def->n_states);
	m->def = def;
	m->obj = obj;
	m->state = initial;
}

const char *co_fsm_state_name(const co_fsm_def *def, int state)
{
	if (!def || state < 0 || state >= def->n_states)
		return "?";
	return def->states[state].name;
}

void co_fsm_goto(co_fsm *m, int next, uint64_t now_us)
{
	/* A table whose enter handlers chain without end is a programming
	 * error; the bound turns it into an assertion, not a hang. */
	for (int chain = 0; next != CO_FSM_STAY; chain++) {
		assert(chain < CO_FSM_MAX_CHAIN);
		assert(next >= 0 && next < m->def->n_states);
		const co_fsm_state *old = &m->def->states[m->state];
		if (old->on_leave)
			old->on_leave(m->obj, now_us);
		m->state = next;
		const co_fsm_state *s = &m->def->states[next];
		next = s->on_enter ? s->on_enter(m->obj, now_us) : CO_FSM_STAY;
	}
}

void co_fsm_frame(co_fsm *m, const co_frame *f, uint64_t now_us)
{
	const co_fsm_state *s = &m->def->states[m->state];
	if (s->on_frame)
		co_fsm_goto(m, s->on_frame(m->obj, f, now_us), now_us);
}

void co_fsm_timeout(co_fsm *m, uint64_t now_us)
{
	const co_fsm_state *s = &m->def->states[m->state];
	if (s->on_timeout)
		co_fsm_goto(m, s->on_timeout(m->obj, now_us), now_us);
}

void co_fsm_con(co_fsm *m, const void *con, uint64_t now_us)
{
	const co_fsm_state *s = &m->def->states[m->state];
	if (s->on_con)
		co_fsm_goto(m, s->on_con(m->obj, con, now_us), now_us);
}
