/* SPDX-License-Identifier: MIT */
/*
 * core/manager_net.c - the network machine of the line (CiA 302-2 NMT
 * start-up, network boot, start and stop of the network).
 */
#include "core/manager_int.h"
#include "core/nmt.h"

bool mgr_all_mandatory_booted(const co_manager *m)
{
	for (unsigned id = 1; id <= 127; id++)
		if (is_mandatory(m, (uint8_t)id) && !m->s[id].d.booted)
			return false;
	return true;
}

/* Start the manager and the slaves (302-2 "NMT start of the network"):
 * one broadcast when 1F80h bit 1 asks for it and every assigned node has
 * booted (a broadcast would otherwise start a wrong device too), else one
 * command per booted node. */
int mgr_start_network_now(co_manager *m, bool explicit, uint64_t now_us)
{
	bool all = true;

	if (co_nmt_get_state(m->node) != CO_NMT_OPERATIONAL)
		(void)co_nmt_local_cmd(m->node, CO_NMT_CS_START, now_us);
	for (unsigned id = 1; id <= 127; id++)
		if (is_bootable(m, (uint8_t)id) &&
		    (!m->s[id].d.booted || m->s[id].target_state != CO_NMT_OPERATIONAL))
			all = false;
	if ((f80(m) & CO_MGR_1F80_START_ALL) && all) {
		mgr_nmt_send(m, 0, CO_NMT_CS_START, now_us);
	} else {
		for (unsigned id = 1; id <= 127; id++) {
			struct mgr_slave *s = &m->s[id];
			if (!s->d.booted || s->expected_state == s->target_state)
				continue;
			if (s->target_state == CO_NMT_OPERATIONAL)
				mgr_nmt_send(m, (uint8_t)id, CO_NMT_CS_START, now_us);
			else if (s->target_state == CO_NMT_STOPPED)
				mgr_nmt_send(m, (uint8_t)id, CO_NMT_CS_STOP, now_us);
		}
	}
	m->net_started = true;
	m->net_started_explicit = explicit;
	m->start_requested = false;
	return CO_MGR_OPERATIONAL;
}

/* The whole-line decisions, after every input (core/manager_int.h, re-entrancy): the
 * network machine's answer to NET_IN_CHECK in the states where the boot
 * can end (BOOTING, WAIT_MANDATORY, and BOOTED while it waits for
 * mandatory slaves). */
static int mgr_check(co_manager *m, uint64_t now_us)
{
	uint8_t st = (uint8_t)co_fsm_state_of(&m->fsm);
	uint32_t b80 = f80(m);
	bool all_attempted = true;

	if (st == CO_MGR_BOOTED && !m->awaiting_mandatory)
		return CO_FSM_STAY;
	for (unsigned id = 1; id <= 127; id++) {
		const struct mgr_slave *s = &m->s[id];
		if (is_bootable(m, (uint8_t)id) && !s->attempted && !s->d.booted &&
		    ((b80 & CO_MGR_1F80_START_ALL) || is_mandatory(m, (uint8_t)id)))
			all_attempted = false;
	}
	if (mgr_all_mandatory_booted(m) && (all_attempted || st != CO_MGR_BOOTING)) {
		m->awaiting_mandatory = false;
		if ((b80 & (CO_MGR_1F80_NO_SELF_START | CO_MGR_1F80_APP_STARTS_SLAVES)) &&
		    !m->start_requested)
			return st != CO_MGR_BOOTED ? CO_MGR_BOOTED : CO_FSM_STAY;
		return mgr_start_network_now(m, m->start_requested, now_us);
	}
	if (st == CO_MGR_BOOTING && all_attempted)
		return CO_MGR_WAIT_MANDATORY;
	return CO_FSM_STAY;
}

static int m_slave_enter(void *obj, uint64_t now_us)
{
	co_manager *m = obj;
	mgr_report_state(m);
	m->net_started = false;
	m->timer_us = CO_NO_DEADLINE;
	/* CiA 302-2 1F80h bit 2: a plain slave enters OPERATIONAL by itself
	 * unless the bit says not to (docs/config.md "self_start") */
	if (!(f80(m) & CO_MGR_1F80_NO_SELF_START) &&
	    co_nmt_get_state(m->node) == CO_NMT_PRE_OPERATIONAL)
		(void)co_nmt_local_cmd(m->node, CO_NMT_CS_START, now_us);
	return CO_FSM_STAY;
}

/* 302-2 NMT start-up: "NMT reset communication all nodes", one by one
 * when a slave has the keep-alive bit (so that one is not reset). */
static int m_resetting_enter(void *obj, uint64_t now_us)
{
	co_manager *m = obj;
	bool keep_alive = false;
	uint8_t cs = m->reset_cs ? m->reset_cs : CO_NMT_CS_RESET_COMM;

	mgr_report_state(m);
	m->reset_cs = 0;
	m->cnt.network_boots++;
	m->net_started = false;
	m->net_started_explicit = false;
	m->boot_time_expired = false;
	m->awaiting_mandatory = false;
	m->start_requested = false;
	for (unsigned id = 1; id <= 127; id++) {
		struct mgr_slave *s = &m->s[id];
		co_fsm_goto(&s->fsm, BS_IDLE, now_us);
		s->attempted = false;
		s->ever_booted = false;
		s->d.booted = false;
		s->lost = false;
		s->mismatch = false;
		s->last_fail = 0;
		s->boot_deferred = false;
		if (is_slave(m, (uint8_t)id) &&
		    (assignment(m, (uint8_t)id) & CO_MGR_1F81_KEEP_ALIVE))
			keep_alive = true;
	}
	if (!keep_alive) {
		mgr_nmt_send(m, 0, cs, now_us);
	} else {
		for (unsigned id = 1; id <= 127; id++)
			if (is_slave(m, (uint8_t)id) &&
			    !(assignment(m, (uint8_t)id) & CO_MGR_1F81_KEEP_ALIVE))
				mgr_nmt_send(m, (uint8_t)id, cs, now_us);
	}
	return CO_MGR_BOOTING;
}

/* 302-2: "boot slave process" for every assigned slave, in parallel; the
 * boot time (1F89h) starts here. */
static int m_booting_enter(void *obj, uint64_t now_us)
{
	co_manager *m = obj;
	uint32_t bt = od_u32(m, 0x1F89, 0);

	mgr_report_state(m);
	m->boot_started_us = now_us;
	m->timer_us = bt ? now_us + (uint64_t)bt * 1000u : CO_NO_DEADLINE;
	for (unsigned id = 1; id <= 127; id++) {
		struct mgr_slave *s = &m->s[id];
		uint32_t a = assignment(m, (uint8_t)id);
		if (!(a & CO_MGR_1F81_SLAVE))
			continue;
		mgr_boot_begin(s, true, !(a & CO_MGR_1F81_KEEP_ALIVE), now_us);
	}
	m->check_pending = true;
	return CO_FSM_STAY;
}

/* 302-2: the boot time ran out with mandatory slaves missing: report
 * them (their last status, B if none), stop retrying them (the scan and
 * boot-ups still find them), do not start the network. */
static int m_boot_time_out(void *obj, uint64_t now_us)
{
	co_manager *m = obj;
	(void)now_us;
	m->timer_us = CO_NO_DEADLINE;
	m->boot_time_expired = true;
	for (unsigned id = 1; id <= 127; id++) {
		struct mgr_slave *s = &m->s[id];
		if (!is_mandatory(m, (uint8_t)id) || s->d.booted)
			continue;
		s->last_fail = 0; /* always reported */
		mgr_emit_boot(s, CO_MGR_STEP_BOOT_TIME, s->d.status ? s->d.status : 'B', s->d.abort,
			      0x1F89, 0, od_u32(m, 0x1F89, 0), 0, true);
		if (bs_state(s) == BS_FAILED)
			s->timer_us = CO_NO_DEADLINE;
	}
	m->awaiting_mandatory = true;
	return CO_MGR_BOOTED;
}

static int m_fatal_enter(void *obj, uint64_t now_us)
{
	co_manager *m = obj;
	mgr_report_state(m);
	m->net_started = false;
	m->timer_us = CO_NO_DEADLINE;
	for (unsigned id = 1; id <= 127; id++)
		co_fsm_goto(&m->s[id].fsm, BS_IDLE, now_us);
	return CO_FSM_STAY;
}

static int m_net_enter(void *obj, uint64_t now_us)
{
	co_manager *m = obj;
	(void)now_us;
	mgr_report_state(m);
	m->timer_us = CO_NO_DEADLINE;
	return CO_FSM_STAY;
}

/* 302-2 network stopped: the boots that run and the retries of failed
 * nodes wait until the network leaves STOPPED (mgr_boot_hold_stopped); a request
 * already on the bus is disowned. */
static int m_stopped_enter(void *obj, uint64_t now_us)
{
	co_manager *m = obj;
	m->start_requested = false;
	for (unsigned id = 1; id <= 127; id++) {
		struct mgr_slave *s = &m->s[id];
		if (bs_running(s) || (bs_state(s) == BS_FAILED && s->timer_us != CO_NO_DEADLINE)) {
			co_fsm_goto(&s->fsm, BS_IDLE, now_us);
			s->boot_deferred = true;
		}
	}
	return m_net_enter(obj, now_us);
}

/* 302-2: first pass over, mandatory slaves still missing; they are
 * retried until the boot time (1F89h) runs out */
static int m_wait_enter(void *obj, uint64_t now_us)
{
	(void)now_us;
	mgr_report_state(obj);
	return CO_FSM_STAY;
}

/* A mandatory slave lost error control and 1F80h bit 4 asks to "reset
 * all nodes, including itself" (CiA 302-2, NMT master start-up, error
 * handling): our own node leaves OPERATIONAL like the others and is
 * started again with the network; its OD is kept (a reset of it would
 * lose what clients wrote through the mailbox). */
static int reset_all_on_error(co_manager *m, uint64_t now_us)
{
	(void)co_nmt_local_cmd(m->node, CO_NMT_CS_ENTER_PREOP, now_us);
	m->reset_cs = CO_NMT_CS_RESET_NODE;
	return CO_MGR_RESETTING;
}

/* ... and 1F80h bit 6 asks to stop all nodes. */
static void stop_all_on_error(co_manager *m, uint64_t now_us)
{
	mgr_nmt_send(m, 0, CO_NMT_CS_STOP, now_us);
	m->net_started = false;
}

/* The inputs every state but FATAL reacts to alike. */
static int m_con(void *obj, const void *con, uint64_t now_us)
{
	const struct mgr_net_in *in = con;
	switch (in->kind) {
	case NET_IN_OWN_ID_CONFLICT:
		return CO_MGR_FATAL;
	case NET_IN_RESET_ALL_ON_ERROR:
		return reset_all_on_error(obj, now_us);
	case NET_IN_STOP_ALL_ON_ERROR:
		stop_all_on_error(obj, now_us);
		return CO_MGR_STOPPED;
	default:
		return CO_FSM_STAY;
	}
}

/* While the boot can end: the check, and the common inputs. */
static int m_boot_con(void *obj, const void *con, uint64_t now_us)
{
	const struct mgr_net_in *in = con;
	return in->kind == NET_IN_CHECK ? mgr_check(obj, now_us) : m_con(obj, con, now_us);
}

/* Stopped already: a stop on error sends the stop and stays. */
static int m_stopped_con(void *obj, const void *con, uint64_t now_us)
{
	const struct mgr_net_in *in = con;
	if (in->kind != NET_IN_STOP_ALL_ON_ERROR)
		return m_con(obj, con, now_us);
	stop_all_on_error(obj, now_us);
	return CO_FSM_STAY;
}

/* FATAL reacts to nothing: only a request (boot the network) leaves it. */
static const co_fsm_state mgr_states[CO_MGR_STATE_COUNT] = {
	[CO_MGR_SLAVE] = { .name = "slave", .on_enter = m_slave_enter, .on_con = m_con },
	[CO_MGR_RESETTING] = { .name = "resetting",
			       .on_enter = m_resetting_enter,
			       .on_con = m_con },
	[CO_MGR_BOOTING] = { .name = "booting",
			     .on_enter = m_booting_enter,
			     .on_timeout = m_boot_time_out,
			     .on_con = m_boot_con },
	[CO_MGR_WAIT_MANDATORY] = { .name = "wait-mandatory",
				    .on_enter = m_wait_enter,
				    .on_timeout = m_boot_time_out,
				    .on_con = m_boot_con },
	[CO_MGR_BOOTED] = { .name = "booted", .on_enter = m_net_enter, .on_con = m_boot_con },
	[CO_MGR_OPERATIONAL] = { .name = "operational", .on_enter = m_net_enter, .on_con = m_con },
	[CO_MGR_STOPPED] = { .name = "stopped",
			     .on_enter = m_stopped_enter,
			     .on_con = m_stopped_con },
	[CO_MGR_PREOP] = { .name = "pre-operational", .on_enter = m_net_enter, .on_con = m_con },
	[CO_MGR_FATAL] = { .name = "fatal", .on_enter = m_fatal_enter },
};

const co_fsm_def mgr_net_def = { "manager", mgr_states, CO_MGR_STATE_COUNT };

/* The network left STOPPED (the line is in its next state already): the
 * nodes held stopped are booted now. */
void mgr_boot_deferred_nodes(co_manager *m, uint64_t now_us)
{
	for (unsigned id = 1; id <= 127; id++) {
		struct mgr_slave *s = &m->s[id];
		if (!s->boot_deferred)
			continue;
		s->boot_deferred = false;
		/* it was stopped: no SDO before it is pre-operational again */
		mgr_nmt_send(m, (uint8_t)id, CO_NMT_CS_ENTER_PREOP, now_us);
		mgr_boot_begin(s, false, false, now_us);
		m->check_pending = true;
	}
}

/* Start of a stopped network (Request NMT start all, or the application's
 * start): with every mandatory slave booted it starts at once; else the
 * line waits in BOOTED for them (held and missing ones are booted now) and
 * starts when they have booted. */
void mgr_start_from_stopped(co_manager *m, uint64_t now_us)
{
	if (mgr_all_mandatory_booted(m)) {
		m->awaiting_mandatory = false;
		co_fsm_goto(&m->fsm, mgr_start_network_now(m, true, now_us), now_us);
	} else {
		m->awaiting_mandatory = true;
		m->start_requested = true; /* whatever 1F80h bits 2/3 say */
		co_fsm_goto(&m->fsm, CO_MGR_BOOTED, now_us);
	}
	mgr_boot_deferred_nodes(m, now_us);
	for (unsigned id = 1; id <= 127; id++) {
		struct mgr_slave *s = &m->s[id];
		if (is_mandatory(m, (uint8_t)id) && is_bootable(m, (uint8_t)id) && !s->d.booted &&
		    !bs_running(s)) {
			mgr_boot_begin(s, false, false, now_us);
			m->check_pending = true;
		}
	}
}
