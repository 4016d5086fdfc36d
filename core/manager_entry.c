/* SPDX-License-Identifier: MIT */
/*
 * core/manager_entry.c - the way into the manager and NMT commands out
 * (see core/manager_int.h: re-entrancy).
 */
#include "core/manager_int.h"

#include "core/nmt.h"

/* ---- NMT output --------------------------------------------------------------- */

static uint8_t cs_result(uint8_t cs)
{
	switch (cs) {
	case CO_NMT_CS_START:
		return CO_NMT_OPERATIONAL;
	case CO_NMT_CS_STOP:
		return CO_NMT_STOPPED;
	default:
		return CO_NMT_PRE_OPERATIONAL; /* resets end pre-op */
	}
}

void mgr_nmt_send(co_manager *m, uint8_t target, uint8_t cs, uint64_t now_us)
{
	(void)co_nmt_master_send(m->node, target, cs, now_us);
	for (unsigned id = 1; id <= 127; id++) {
		struct mgr_slave *s = &m->s[id];
		if (target && target != id)
			continue;
		s->expected_state = cs_result(cs);
		s->cmd_since_bootup = true;
		if (cs == CO_NMT_CS_RESET_NODE || cs == CO_NMT_CS_RESET_COMM)
			s->bootup_since_reset = false;
	}
}

static void wake_waiting(co_manager *m, uint64_t now_us)
{
	struct mgr_in in = { .kind = IN_CHANNEL };
	/* mandatory slaves first (the network waits for them, CiA 302-2
	 * 1F81h bit 3), then by ID */
	for (int pass = 0; pass < 2; pass++)
		for (unsigned id = 1; id <= 127; id++) {
			struct mgr_slave *s = &m->s[id];
			if (bs_state(s) == BS_WAIT_CHANNEL &&
			    is_mandatory(m, (uint8_t)id) == (pass == 0))
				bs_input(s, &in, now_us);
		}
}

void mgr_net_input(co_manager *m, enum net_in_kind kind, uint64_t now_us)
{
	const struct mgr_net_in in = { .kind = kind };
	co_fsm_con(&m->fsm, &in, now_us);
}

void mgr_enter(co_manager *m, uint64_t now_us)
{
	if (now_us > m->node->now_us)
		m->node->now_us = now_us;
	m->depth++;
}

void mgr_after(co_manager *m, uint64_t now_us)
{
	if (--m->depth > 0)
		return;
	m->depth++;
	for (int guard = 0; guard < 8 && (m->wake_pending || m->check_pending); guard++) {
		if (m->wake_pending) {
			m->wake_pending = false;
			wake_waiting(m, now_us);
		}
		if (m->check_pending) {
			m->check_pending = false;
			mgr_net_input(m, NET_IN_CHECK, now_us);
		}
	}
	mgr_report_state(m);
	m->depth--;
}
