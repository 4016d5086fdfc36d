/* SPDX-License-Identifier: MIT */
/*
 * core/manager_supervise.c - inputs from the core: boot-ups, heartbeat
 * and guarding, EMCY, frames on the manager's own node-ID, NMT commands
 * from the bus; and the scan for missing nodes.
 */
#include <string.h>

#include "core/commfault.h"
#include "core/guarding.h"
#include "core/heartbeat.h"
#include "core/manager_int.h"
#include "core/nmt.h"
#include "core/sdo_client.h"

/* An episode of another device on the manager's own node-ID began
 * (core/commfault.h: a boot-up or heartbeat on 700h+id): a node-ID
 * conflict (CiA 301 wants node-IDs unique). The manager halts the line's
 * NMT start-up and supervision until the episode ends (docs/config.md "A
 * device on the manager's node-ID"). */
static void own_id_conflict(co_manager *m, uint64_t now_us)
{
	if (!is_master(m) || co_fsm_state_of(&m->fsm) == CO_MGR_FATAL)
		return;
	m->cnt.duplicates++;
	mgr_note_first_error(m, m->own_id, 0, 0);
	mgr_emit_node(m, m->own_id, CO_MGR_NODE_OWN_ID, CO_NMT_ERRCTRL_BASE + m->own_id);
	mgr_net_input(m, NET_IN_OWN_ID_CONFLICT, now_us);
	m->fatal_by_conflict = co_fsm_state_of(&m->fsm) == CO_MGR_FATAL;
}

/* The other device has been silent for the quiet time: the network is
 * booted again, as `cogwctl boot LINE` would (the nodes' states are not
 * known after the halt; keep-alive nodes stay operational). */
static void own_id_conflict_over(co_manager *m, uint64_t now_us)
{
	if (!m->fatal_by_conflict || co_fsm_state_of(&m->fsm) != CO_MGR_FATAL)
		return;
	m->fatal_by_conflict = false;
	m->own_id_frame_reported = 0;
	co_fsm_goto(&m->fsm, CO_MGR_RESETTING, now_us);
}

static void on_comm_fault(co_manager *m, const co_ev_commfault *cf, uint64_t now_us)
{
	if (cf->fault != CO_COMM_FAULT_ID_COLLISION)
		return;
	mgr_enter(m, now_us);
	if (cf->active)
		own_id_conflict(m, now_us);
	else
		own_id_conflict_over(m, now_us);
	mgr_after(m, now_us);
}

/* Any other frame on our own identities (an EMCY on 080h+id, an SDO answer
 * on 580h+id, a 700h+id frame that is no error-control message): one
 * frame proves no second device and anyone on the bus can send it, so it
 * is counted and reported once per network boot and kind, and boot and
 * supervision go on. */
static void own_id_frame(co_manager *m, uint32_t cob_id)
{
	unsigned kind = cob_id >= CO_NMT_ERRCTRL_BASE ? 0 : cob_id >= SDO_COB_TX_BASE ? 2 : 1;
	m->cnt.own_id_frames++;
	if (m->own_id_frame_reported & (1u << kind))
		return;
	m->own_id_frame_reported |= (uint8_t)(1u << kind);
	mgr_emit_node(m, m->own_id, CO_MGR_NODE_OWN_ID, cob_id);
}

void mgr_own_id_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	co_manager *m = arg;
	(void)node;
	/* a remote request on 700h+id is someone guarding us; a boot-up or
	 * heartbeat is core/commfault.c's (an episode, on_comm_fault) */
	if (!is_master(m) || (f->id >= CO_NMT_ERRCTRL_BASE &&
			      (f->flags & CO_FRAME_RTR || co_commfault_is_errctrl_message(f))))
		return;
	mgr_enter(m, now_us);
	own_id_frame(m, f->id);
	mgr_after(m, now_us);
}

static void duplicate(co_manager *m, struct mgr_slave *s, uint32_t why)
{
	if (s->dup_reported)
		return;
	s->dup_reported = true;
	m->cnt.duplicates++;
	mgr_emit_node(m, s->id, CO_MGR_NODE_DUPLICATE, why);
}

static void unexpected(co_manager *m, struct mgr_slave *s)
{
	if (s->unexpected_reported)
		return;
	s->unexpected_reported = true;
	m->cnt.unexpected++;
	mgr_emit_node(m, s->id, CO_MGR_NODE_UNEXPECTED, 0);
}

static void on_bootup(co_manager *m, struct mgr_slave *s, uint64_t now_us)
{
	struct mgr_in in = { .kind = IN_BOOTUP };
	uint8_t mst = (uint8_t)co_fsm_state_of(&m->fsm);

	s->bootup_us = now_us;
	s->bootup_since_reset = true;
	s->last_state = CO_NMT_PRE_OPERATIONAL; /* boot-up ends in pre-op */
	s->cmd_since_bootup = false;
	s->expected_state = CO_NMT_PRE_OPERATIONAL;
	s->dup_reported = false;
	if (!is_slave(m, s->id)) {
		unexpected(m, s);
		return;
	}
	if (!mgr_active(m) || mst == CO_MGR_RESETTING)
		return;
	switch (bs_state(s)) {
	case BS_WAIT_BOOTUP:
	case BS_KEEP_ALIVE:
		bs_input(s, &in, now_us);
		return;
	case BS_CONFIGURE:
		/* CiA 302-3 restore configuration (1F81h bit 7, 1F8Ah): the
		 * configure step itself resets the node and waits for this
		 * boot-up; the boot slave process goes on where it is. */
		if (assignment(m, s->id) & CO_MGR_1F81_RESTORE)
			return;
		break;
	default:
		break;
	}
	if (!is_bootable(m, s->id) && bs_state(s) == BS_BOOTED)
		return;
	if (mgr_boot_hold_stopped(s, now_us))
		return;
	/* late or rebooted node: its boot slave process runs again */
	/* late: it was looked for and missing, and shows up now */
	if (!s->ever_booted && s->attempted)
		mgr_emit_node(m, s->id, CO_MGR_NODE_LATE, 0);
	if (s->lost)
		mgr_emit_node(m, s->id, CO_MGR_NODE_BACK, 0);
	s->d.booted = false;
	mgr_boot_begin(s, false, false, now_us);
	m->check_pending = true;
}

/* Error control lost (E: heartbeat, F: guarding) for a booted slave:
 * the 1F80h reaction for a mandatory one, else that node alone is reset
 * and booted again when it comes back. */
static void on_errctrl_lost(co_manager *m, struct mgr_slave *s, char letter, uint64_t now_us)
{
	uint32_t b80 = f80(m);

	s->last_state = STATE_UNKNOWN;
	if (bs_state(s) != BS_BOOTED || !mgr_active(m))
		return;
	s->lost = true;
	s->d.booted = false;
	s->d.status = letter;
	s->d.abort = 0;
	s->d.index = letter == 'E' ? 0x1016 : 0x1F81;
	s->d.sub = letter == 'E' ? 0 : s->id;
	m->cnt.errctrl_events++;
	mgr_note_first_error(m, s->id, letter, 0);
	mgr_emit_node(m, s->id, CO_MGR_NODE_LOST, (uint32_t)letter);
	co_fsm_goto(&s->fsm, BS_IDLE, now_us);
	if (letter == 'F')
		(void)co_guard_master_remove(m->node, s->id);
	if (is_mandatory(m, s->id) && (b80 & CO_MGR_1F80_RESET_ALL_ON_ERROR)) {
		mgr_emit_node(m, s->id, CO_MGR_NODE_ERROR_REACTION, CO_NMT_CS_RESET_NODE);
		mgr_net_input(m, NET_IN_RESET_ALL_ON_ERROR, now_us);
		return;
	}
	if (is_mandatory(m, s->id) && (b80 & CO_MGR_1F80_STOP_ALL_ON_ERROR)) {
		mgr_emit_node(m, s->id, CO_MGR_NODE_ERROR_REACTION, CO_NMT_CS_STOP);
		mgr_net_input(m, NET_IN_STOP_ALL_ON_ERROR, now_us);
		return;
	}
	mgr_emit_node(m, s->id, CO_MGR_NODE_ERROR_REACTION, 0);
	mgr_nmt_send(m, s->id, CO_NMT_CS_RESET_COMM, now_us);
	m->check_pending = true;
}

/* A node that just sent its boot-up is pre-operational; it reporting
 * OPERATIONAL or STOPPED before anybody told it so means a second device
 * answers on that ID (or the first never rebooted). `mine` is the state
 * the manager heard before this one. */
static bool second_device_state(const co_manager *m, const struct mgr_slave *s, uint8_t st,
				uint8_t prev, uint8_t mine, bool guarded)
{
	return s->bootup_us && !s->cmd_since_bootup && !guarded &&
	       (st == CO_NMT_OPERATIONAL || st == CO_NMT_STOPPED) &&
	       (mine == CO_NMT_PRE_OPERATIONAL || prev == CO_NMT_INITIALISING) &&
	       !(assignment(m, s->id) & CO_MGR_1F81_KEEP_ALIVE);
}

/* KEEP_OP (docs/config.md, nodes[].keep_op): a booted node left
 * OPERATIONAL without being told: started again. */
static void keep_op_check(co_manager *m, struct mgr_slave *s, uint8_t st, uint8_t prev,
			  uint64_t now_us)
{
	if (!s->keep_op || bs_state(s) != BS_BOOTED || prev != CO_NMT_OPERATIONAL ||
	    st == CO_NMT_OPERATIONAL || s->expected_state != CO_NMT_OPERATIONAL || !m->net_started)
		return;
	m->cnt.keep_op_restarts++;
	mgr_emit_node(m, s->id, CO_MGR_NODE_KEEP_OP, st);
	mgr_nmt_send(m, s->id, CO_NMT_CS_START, now_us);
}

static void on_state(co_manager *m, struct mgr_slave *s, uint8_t st, uint8_t prev, bool guarded,
		     uint64_t now_us)
{
	struct mgr_in in = { .kind = IN_HB, .value = st, .guarded = guarded };
	uint8_t mine = s->last_state;
	s->last_state = st;
	if (!is_slave(m, s->id)) {
		unexpected(m, s);
		return;
	}
	if (second_device_state(m, s, st, prev, mine, guarded))
		duplicate(m, s, st);
	if (bs_state(s) == BS_KEEP_ALIVE || (guarded && bs_state(s) == BS_ERRCTRL))
		bs_input(s, &in, now_us);
	keep_op_check(m, s, st, prev, now_us);
}

static void on_emcy(co_manager *m, struct mgr_slave *s, const co_ev_emcy *e, uint64_t now_us)
{
	co_mgr_emcy_rec *r = &s->d.emcy[s->d.emcy_next];
	r->time_us = now_us;
	r->code = e->code;
	r->reg = e->reg;
	memcpy(r->msef, e->msef, sizeof(r->msef));
	s->d.emcy_next = (uint8_t)((s->d.emcy_next + 1) % CO_MGR_EMCY_HISTORY);
	if (s->d.emcy_count < CO_MGR_EMCY_HISTORY)
		s->d.emcy_count++;
	/* error code 0000h / register 0 = "error reset or no error" */
	s->emcy_active = e->code != 0 || e->reg != 0;
	if (s->emcy_active)
		mgr_note_first_error(m, s->id, 0, e->code);
}

/* Heartbeat or guarding of a node that was lost came back: its boot
 * slave process waits for that in ERRCTRL, or it is booted again. */
static void on_errctrl_back(co_manager *m, struct mgr_slave *s, const co_ev_errctrl *ec,
			    uint64_t now_us)
{
	struct mgr_in in = { .kind = IN_HB, .guarded = ec->guarded };
	if (ec->state != CO_HB_STATE_UNKNOWN)
		s->last_state = ec->state;
	if (bs_state(s) == BS_ERRCTRL) {
		bs_input(s, &in, now_us);
	} else if (s->lost && bs_state(s) == BS_IDLE && mgr_active(m) && is_bootable(m, s->id)) {
		mgr_emit_node(m, s->id, CO_MGR_NODE_BACK, 0);
		mgr_boot_begin(s, false, false, now_us);
	}
}

static void on_errctrl_kind(co_manager *m, struct mgr_slave *s, co_event_kind kind,
			    const co_ev_errctrl *ec, uint64_t now_us)
{
	switch (kind) {
	case CO_EV_BOOTUP:
		on_bootup(m, s, now_us);
		break;
	case CO_EV_HB_STATE:
		on_state(m, s, ec->state, ec->prev, ec->guarded, now_us);
		break;
	case CO_EV_HB_STARTED:
	case CO_EV_GUARD_RESUMED:
		on_errctrl_back(m, s, ec, now_us);
		break;
	case CO_EV_HB_LOST:
		on_errctrl_lost(m, s, 'E', now_us);
		break;
	case CO_EV_GUARD_FAILED:
		on_errctrl_lost(m, s, 'F', now_us);
		break;
	default:
		break;
	}
}

/* Boot-up, heartbeat and guarding events of the nodes (another device on
 * the manager's own node-ID comes as a communication fault). */
static void on_errctrl_event(co_manager *m, const co_event *ev)
{
	const co_ev_errctrl *ec = &ev->u.errctrl;
	uint64_t now = ev->now_us;

	if (ec->node < 1 || ec->node > 127 || ec->node == m->own_id)
		return;
	if (!is_master(m) && co_fsm_state_of(&m->fsm) == CO_MGR_SLAVE)
		return;
	mgr_enter(m, now);
	on_errctrl_kind(m, &m->s[ec->node], ev->kind, ec, now);
	mgr_after(m, now);
}

/* Two answers to one SDO request: two devices on that ID. */
static void on_second_answer(co_manager *m, const co_ev_sdo_cli *c, uint64_t now_us)
{
	if (c->node_id < 1 || c->node_id > 127 || c->node_id == m->own_id)
		return;
	mgr_enter(m, now_us);
	duplicate(m, &m->s[c->node_id], CO_MGR_DUP_SDO_ANSWERS);
	mgr_after(m, now_us);
}

void co_manager_on_event(co_manager *m, const co_event *ev)
{
	uint64_t now = ev->now_us;

	switch (ev->kind) {
	case CO_EV_BOOTUP:
	case CO_EV_HB_STATE:
	case CO_EV_HB_STARTED:
	case CO_EV_HB_LOST:
	case CO_EV_GUARD_FAILED:
	case CO_EV_GUARD_RESUMED:
		on_errctrl_event(m, ev);
		return;
	case CO_EV_EMCY_RX:
		if (ev->u.emcy.node >= 1 && ev->u.emcy.node <= 127)
			on_emcy(m, &m->s[ev->u.emcy.node], &ev->u.emcy, now);
		return;
	case CO_EV_SDO_CLIENT_SECOND_ANSWER:
		on_second_answer(m, &ev->u.sdo_cli, now);
		return;
	case CO_EV_COMM_FAULT:
		on_comm_fault(m, &ev->u.commfault, now);
		return;
	case CO_EV_NMT_STATE:
		/* our own state is a flag of the line state (manager operational) */
		mgr_enter(m, now);
		mgr_after(m, now);
		return;
	default:
		return;
	}
}

/* NMT commands from the bus addressed to the manager's own node: ignored
 * and counted while it is NMT master (unless configured otherwise). */
bool mgr_nmt_rx_filter(void *ctx, co_node *node, uint8_t cs, uint8_t target, uint64_t now_us)
{
	co_manager *m = ctx;
	(void)node;
	if (m->cfg.accept_remote_nmt || !is_master(m))
		return true;
	mgr_enter(m, now_us);
	m->cnt.nmt_ignored++;
	co_ev_mgr e = {
		.node = m->own_id, .what = CO_MGR_NODE_NMT_IGNORED, .value = cs, .sub = target
	};
	mgr_emit(m, CO_EV_MGR_NODE, &e);
	mgr_after(m, now_us);
	return false;
}

/* Scan for missing assigned nodes: nodes neither booted nor booting get
 * their boot slave process again (their 1000h read is the probe). */
void mgr_scan(co_manager *m, uint64_t now_us)
{
	uint8_t st = (uint8_t)co_fsm_state_of(&m->fsm);
	if (st != CO_MGR_BOOTED && st != CO_MGR_OPERATIONAL && st != CO_MGR_PREOP &&
	    st != CO_MGR_WAIT_MANDATORY)
		return;
	for (unsigned id = 1; id <= 127; id++) {
		struct mgr_slave *s = &m->s[id];
		if (!is_bootable(m, (uint8_t)id) || s->d.booted || bs_running(s))
			continue;
		if (bs_state(s) == BS_FAILED && s->mismatch)
			continue; /* present, but the wrong device */
		if (bs_state(s) == BS_FAILED && s->timer_us != CO_NO_DEADLINE)
			continue; /* its own retry is due */
		mgr_boot_begin(s, false, false, now_us);
	}
}
