/* SPDX-License-Identifier: MIT */
/*
 * core/manager_request.c - the application's requests (core/manager.h):
 * boot, start, Request NMT, the ends of the configure and software steps.
 */
#include <errno.h>
#include <string.h>

#include "core/manager_int.h"
#include "core/nmt.h"

int co_manager_boot_network(co_manager *m, uint64_t now_us)
{
	if (!is_master(m))
		return -EPERM;
	mgr_enter(m, now_us);
	m->autostart_pending = false;
	m->fatal_by_conflict = false;
	m->own_id_frame_reported = 0;
	co_fsm_goto(&m->fsm, CO_MGR_RESETTING, now_us);
	mgr_after(m, now_us);
	return 0;
}

int co_manager_boot_node(co_manager *m, uint8_t node_id, uint64_t now_us)
{
	if (node_id < 1 || node_id > 127 || node_id == m->own_id)
		return -EINVAL;
	if (!mgr_active(m))
		return -EPERM;
	mgr_enter(m, now_us);
	m->s[node_id].d.booted = false;
	mgr_boot_begin(&m->s[node_id], false, false, now_us);
	m->check_pending = true;
	mgr_after(m, now_us);
	return 0;
}

/* CiA 302-2 keeps the network list in the manager's own object 1F81h: a
 * node assigned while the network runs boots like a late node, one whose
 * assignment is withdrawn is no longer booted or supervised. Its bits of
 * the diagnostics go with it; a removed node that stays on the bus is not
 * reported as unexpected until the next network boot (it is known, only
 * no longer managed). */
int co_manager_node_reassigned(co_manager *m, uint8_t node_id, uint64_t now_us)
{
	struct mgr_slave *s;
	uint8_t st;

	if (node_id < 1 || node_id > 127 || node_id == m->own_id)
		return -EINVAL;
	if (!mgr_active(m))
		return 0; /* read at the next network boot */
	st = (uint8_t)co_fsm_state_of(&m->fsm);
	if (st == CO_MGR_RESETTING || st == CO_MGR_BOOTING)
		return -EAGAIN; /* the network boot reads 1F81h itself */
	s = &m->s[node_id];
	mgr_enter(m, now_us);
	if (!is_slave(m, node_id)) {
		co_fsm_goto(&s->fsm, BS_IDLE, now_us);
		s->d.booted = false;
		s->d.assignment = 0;
		s->d.status = 0;
		s->lost = false;
		s->mismatch = false;
		s->boot_deferred = false;
		s->emcy_active = false;
		s->unexpected_reported = true;
	} else {
		s->unexpected_reported = false;
		s->d.booted = false;
		if (is_bootable(m, node_id))
			mgr_boot_begin(s, false, false, now_us);
		else
			co_fsm_goto(&s->fsm, BS_IDLE, now_us);
	}
	m->check_pending = true;
	mgr_after(m, now_us);
	return 0;
}

int co_manager_start_network(co_manager *m, uint64_t now_us)
{
	bool stopped = co_fsm_state_of(&m->fsm) == CO_MGR_STOPPED;
	if (!mgr_active(m))
		return -EPERM;
	if (!stopped && !mgr_all_mandatory_booted(m))
		return -EAGAIN;
	mgr_enter(m, now_us);
	if (stopped) {
		mgr_start_from_stopped(m, now_us);
	} else {
		m->awaiting_mandatory = false;
		co_fsm_goto(&m->fsm, mgr_start_network_now(m, true, now_us), now_us);
	}
	mgr_after(m, now_us);
	return 0;
}

int mgr_cmd_to_cs(uint8_t cmd)
{
	switch (cmd) {
	case CO_MGR_REQ_STOP:
		return CO_NMT_CS_STOP;
	case CO_MGR_REQ_START:
		return CO_NMT_CS_START;
	case CO_MGR_REQ_RESET_NODE:
		return CO_NMT_CS_RESET_NODE;
	case CO_MGR_REQ_RESET_COMM:
		return CO_NMT_CS_RESET_COMM;
	case CO_MGR_REQ_PREOP:
		return CO_NMT_CS_ENTER_PREOP;
	}
	return -EINVAL;
}

static int request_all(co_manager *m, uint8_t cs, uint64_t now_us)
{
	switch (cs) {
	case CO_NMT_CS_START:
		if (co_fsm_state_of(&m->fsm) == CO_MGR_STOPPED) {
			mgr_start_from_stopped(m, now_us);
			return 0;
		}
		if (!mgr_all_mandatory_booted(m))
			return -EAGAIN;
		m->awaiting_mandatory = false;
		co_fsm_goto(&m->fsm, mgr_start_network_now(m, true, now_us), now_us);
		return 0;
	case CO_NMT_CS_STOP:
	case CO_NMT_CS_ENTER_PREOP:
		mgr_nmt_send(m, 0, cs, now_us);
		m->net_started = false;
		co_fsm_goto(&m->fsm, cs == CO_NMT_CS_STOP ? CO_MGR_STOPPED : CO_MGR_PREOP, now_us);
		if (cs == CO_NMT_CS_ENTER_PREOP)
			mgr_boot_deferred_nodes(m, now_us);
		return 0;
	default: /* resets: the network boot runs again */
		m->reset_cs = cs;
		co_fsm_goto(&m->fsm, CO_MGR_RESETTING, now_us);
		return 0;
	}
}

int co_manager_request_nmt(co_manager *m, uint8_t node_id, uint8_t cmd, uint64_t now_us)
{
	int cs = mgr_cmd_to_cs(cmd), rc = 0;

	if (cs < 0 || node_id < 1 || node_id > CO_MGR_ALL_NODES)
		return -EINVAL;
	if (!is_master(m) || co_fsm_state_of(&m->fsm) == CO_MGR_SLAVE)
		return -EPERM;
	mgr_enter(m, now_us);
	{
		co_ev_mgr e = { .node = node_id == CO_MGR_ALL_NODES ? 0 : node_id,
				.what = CO_MGR_NODE_REQUEST_NMT,
				.value = cmd };
		mgr_emit(m, CO_EV_MGR_NODE, &e);
	}
	if (node_id == CO_MGR_ALL_NODES) {
		rc = request_all(m, (uint8_t)cs, now_us);
	} else if (node_id == m->own_id) {
		if (cs == CO_NMT_CS_RESET_NODE || cs == CO_NMT_CS_RESET_COMM) {
			m->reset_cs = 0;
			co_fsm_goto(&m->fsm, CO_MGR_RESETTING, now_us);
		} else {
			rc = co_nmt_local_cmd(m->node, (uint8_t)cs, now_us);
		}
	} else {
		struct mgr_slave *s = &m->s[node_id];
		mgr_nmt_send(m, node_id, (uint8_t)cs, now_us);
		if (cs == CO_NMT_CS_RESET_NODE || cs == CO_NMT_CS_RESET_COMM) {
			/* its boot runs again on its boot-up */
			s->d.booted = false;
			if (mgr_active(m))
				co_fsm_goto(&s->fsm, BS_IDLE, now_us);
			m->check_pending = true;
		}
	}
	mgr_after(m, now_us);
	return rc;
}

/* The outcome of a boot step another module carries out (configure,
 * software, PDO layout) for a node waiting in state `step`: fed to its boot
 * machine as an input. -EINVAL (no such node), -ENOENT (not in that step). */
static int step_done(co_manager *m, uint8_t node_id, int step, const struct mgr_in *in,
		     uint64_t now_us)
{
	if (node_id < 1 || node_id > 127)
		return -EINVAL;
	if (bs_state(&m->s[node_id]) != step)
		return -ENOENT;
	mgr_enter(m, now_us);
	bs_input(&m->s[node_id], in, now_us);
	mgr_after(m, now_us);
	return 0;
}

int co_manager_configure_done(co_manager *m, uint8_t node_id, uint32_t abort, uint16_t index,
			      uint8_t sub, uint32_t entry, uint64_t now_us)
{
	struct mgr_in in = {
		.kind = IN_CONFIGURED, .abort = abort, .value = entry, .index = index, .sub = sub
	};
	return step_done(m, node_id, BS_CONFIGURE, &in, now_us);
}

int co_manager_software_done(co_manager *m, uint8_t node_id, char status, uint32_t abort,
			     uint16_t index, uint8_t sub, uint32_t value, uint64_t now_us)
{
	struct mgr_in in = { .kind = IN_SOFTWARE,
			     .abort = abort,
			     .index = index,
			     .sub = sub,
			     .found = value,
			     .value = (uint8_t)status };
	if (status && !strchr("GHI", status))
		return -EINVAL;
	return step_done(m, node_id, BS_SOFTWARE, &in, now_us);
}

int co_manager_pdo_layout_done(co_manager *m, uint8_t node_id, uint32_t abort, uint16_t index,
			       uint8_t sub, uint32_t kept, uint32_t dropped, uint64_t now_us)
{
	struct mgr_in in = { .kind = IN_PDO_LAYOUT,
			     .abort = abort,
			     .index = index,
			     .sub = sub,
			     .value = kept,
			     .found = dropped };
	return step_done(m, node_id, BS_PDO_LAYOUT, &in, now_us);
}

int co_manager_set_keep_op(co_manager *m, uint8_t node_id, bool on)
{
	if (node_id < 1 || node_id > 127)
		return -EINVAL;
	m->s[node_id].keep_op = on;
	return 0;
}

int co_manager_set_target_state(co_manager *m, uint8_t node_id, uint8_t nmt_state)
{
	if (node_id < 1 || node_id > 127)
		return -EINVAL;
	if (nmt_state != CO_NMT_OPERATIONAL && nmt_state != CO_NMT_PRE_OPERATIONAL &&
	    nmt_state != CO_NMT_STOPPED)
		return -EINVAL;
	m->s[node_id].target_state = nmt_state;
	return 0;
}
