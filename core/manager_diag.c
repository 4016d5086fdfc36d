/* SPDX-License-Identifier: MIT */
/*
 * core/manager_diag.c - the manager's names, events, line flags,
 * diagnostics and counters.
 */
#include <string.h>

#include "core/manager_int.h"
#include "core/nmt.h"

const char *co_mgr_state_to_string(uint8_t state)
{
	return co_fsm_state_name(&mgr_net_def, state);
}

const char *co_mgr_step_to_string(uint8_t step)
{
	static const char *const n[CO_MGR_STEP_COUNT] = {
		"assignment", "keep-alive", "device-type", "vendor-id",     "product-code",
		"revision",   "serial",     "configure",   "error-control", "start",
		"boot-time",  "software",   "pdo-layout",
	};
	return step < CO_MGR_STEP_COUNT ? n[step] : "?";
}

/* The error status letters of the boot slave process (CiA 302-2). */
const char *co_mgr_status_to_string(char status)
{
	static const char *const text['O' - 'A' + 1] = {
		"not in the network list (1F81h)",
		"no answer to the read of 1000h",
		"device type differs from 1F84h",
		"vendor-ID differs from 1F85h",
		"heartbeat event",
		"node guarding event",
		"program download objects not configured",
		"software update required but not allowed",
		"program download failed",
		"configuration download failed",
		"no heartbeat during the start of error control",
		"slave was operational already (keep-alive)",
		"product code differs from 1F86h",
		"revision number differs from 1F87h",
		"serial number differs from 1F88h",
	};
	if (status == 0)
		return "ok";
	return status >= 'A' && status <= 'O' ? text[status - 'A'] : "?";
}

const char *co_mgr_node_what_to_string(uint8_t what)
{
	static const char *const n[CO_MGR_NODE_WHAT_COUNT] = {
		"unexpected",  "late",    "lost",        "back",           "duplicate", "own-id",
		"nmt-ignored", "keep-op", "request-nmt", "error-reaction", "program",
	};
	return what < CO_MGR_NODE_WHAT_COUNT ? n[what] : "?";
}

void mgr_emit(co_manager *m, co_event_kind kind, const co_ev_mgr *e)
{
	co_event ev = { .kind = kind };
	ev.u.mgr = *e;
	co_node_emit(m->node, &ev);
}

void mgr_note_first_error(co_manager *m, uint8_t id, char status, uint32_t code)
{
	if (m->cnt.first_error_node)
		return;
	m->cnt.first_error_node = id;
	m->cnt.first_error_status = status;
	m->cnt.first_error_code = code;
}

void mgr_emit_node(co_manager *m, uint8_t id, uint8_t what, uint32_t value)
{
	co_ev_mgr e = {
		.node = id, .what = what, .value = value, .mandatory = is_mandatory(m, id)
	};
	mgr_emit(m, CO_EV_MGR_NODE, &e);
}

/* One step of a boot slave process: status 0 = passed. Failures that
 * repeat the previous one exactly (a node retried every second) are counted
 * but not reported again. */
void mgr_emit_boot(struct mgr_slave *s, uint8_t step, char status, uint32_t abort, uint16_t index,
		   uint8_t sub, uint32_t value, uint32_t expected, bool done)
{
	co_manager *m = s->m;
	co_ev_mgr e = { .node = s->id,
			.step = step,
			.status = status,
			.abort = abort,
			.index = index,
			.sub = sub,
			.value = value,
			.expected = expected,
			.done = done,
			.mandatory = is_mandatory(m, s->id) };

	if (step == CO_MGR_STEP_BOOT_TIME) {
		/* reports the node's last failure; its details stay as they are */
		mgr_note_first_error(m, s->id, status, abort);
		e.flags = mgr_compute_flags(m);
		mgr_emit(m, CO_EV_MGR_BOOT, &e);
		return;
	}
	s->d.step = step;
	if (status && status != 'L') {
		bool repeat = s->last_fail == status && s->last_fail_step == step &&
			      s->last_fail_abort == abort;
		s->d.status = status;
		s->d.abort = abort;
		s->d.index = index;
		s->d.sub = sub;
		s->d.value = value;
		s->d.fail_count++;
		mgr_note_first_error(m, s->id, status, abort);
		s->last_fail = status;
		s->last_fail_step = step;
		s->last_fail_abort = abort;
		if (repeat)
			return;
	}
	e.flags = mgr_compute_flags(m);
	mgr_emit(m, CO_EV_MGR_BOOT, &e);
}

uint8_t mgr_compute_flags(const co_manager *m)
{
	uint8_t f = 0;
	uint8_t st = co_fsm_state_of(&m->fsm);

	if (co_nmt_get_state(m->node) == CO_NMT_OPERATIONAL)
		f |= CO_MGR_F_MANAGER_OPERATIONAL;
	if (st == CO_MGR_SLAVE)
		return f;
	for (unsigned id = 1; id <= 127; id++) {
		const struct mgr_slave *s = &m->s[id];
		uint32_t a = assignment(m, (uint8_t)id);
		if (s->last_state == CO_NMT_OPERATIONAL && (a & CO_MGR_1F81_SLAVE))
			f |= CO_MGR_F_SLAVE_OPERATIONAL;
		if (s->unexpected_reported && s->last_state != STATE_UNKNOWN &&
		    !(a & CO_MGR_1F81_SLAVE))
			f |= CO_MGR_F_OPTIONAL_MISSING;
		if (!(a & CO_MGR_1F81_SLAVE) || !(a & CO_MGR_1F81_BOOT) || s->d.booted)
			continue;
		if (st == CO_MGR_RESETTING || (st == CO_MGR_BOOTING && !s->attempted))
			continue; /* not decided yet */
		f |= (a & CO_MGR_1F81_MANDATORY) ? CO_MGR_F_MANDATORY_MISSING
						 : CO_MGR_F_OPTIONAL_MISSING;
	}
	return f;
}

void mgr_report_state(co_manager *m)
{
	uint8_t st = (uint8_t)co_fsm_state_of(&m->fsm);
	uint8_t fl = mgr_compute_flags(m);
	co_ev_mgr e = { .state = st, .prev = m->reported_state, .flags = fl };

	if (m->reported_once && st == m->reported_state && fl == m->reported_flags)
		return;
	m->reported_once = true;
	m->reported_state = st;
	m->reported_flags = fl;
	mgr_emit(m, CO_EV_MGR_STATE, &e);
}

uint8_t co_manager_state(const co_manager *m)
{
	return (uint8_t)co_fsm_state_of(&m->fsm);
}

uint8_t co_manager_flags(const co_manager *m)
{
	return mgr_compute_flags(m);
}

static void bit_set(co_mgr_bits *b, unsigned n)
{
	b->w[n / 32] |= 1u << (n % 32);
}

void co_manager_get_diag(const co_manager *m, co_mgr_diag *out)
{
	*out = m->cnt;
	memset(&out->assigned, 0, sizeof(co_mgr_bits) * 9);
	out->state = co_manager_state(m);
	out->flags = mgr_compute_flags(m);
	for (unsigned id = 1; id <= 127; id++) {
		const struct mgr_slave *s = &m->s[id];
		if (is_slave(m, (uint8_t)id))
			bit_set(&out->assigned, id);
		if (s->last_state != STATE_UNKNOWN)
			bit_set(&out->present, id);
		if (s->d.booted)
			bit_set(&out->booted, id);
		if (s->last_state == CO_NMT_OPERATIONAL)
			bit_set(&out->operational, id);
		if (s->last_state == CO_NMT_STOPPED)
			bit_set(&out->stopped, id);
		if (s->last_state == CO_NMT_PRE_OPERATIONAL)
			bit_set(&out->preop, id);
		if (s->mismatch || (s->unexpected_reported && s->last_state != STATE_UNKNOWN))
			bit_set(&out->mismatch, id);
		if (s->lost)
			bit_set(&out->errctrl_lost, id);
		if (s->emcy_active)
			bit_set(&out->emcy_active, id);
	}
}

const co_mgr_node_diag *co_manager_node_diag(const co_manager *m, uint8_t node_id)
{
	if (node_id < 1 || node_id > 127)
		return NULL;
	((co_manager *)m)->s[node_id].d.bs_state = (uint8_t)bs_state(&m->s[node_id]);
	return &m->s[node_id].d;
}

void co_manager_reset_counters(co_manager *m)
{
	m->cnt.first_error_node = 0;
	m->cnt.first_error_status = 0;
	m->cnt.first_error_code = 0;
	m->cnt.nmt_ignored = 0;
	m->cnt.unexpected = 0;
	m->cnt.duplicates = 0;
	m->cnt.errctrl_events = 0;
	m->cnt.keep_op_restarts = 0;
	m->cnt.network_boots = 0;
	m->cnt.own_id_frames = 0;
	for (unsigned id = 1; id <= 127; id++) {
		co_mgr_node_diag *d = &m->s[id].d;
		d->boot_count = 0;
		d->fail_count = 0;
		d->emcy_count = 0;
		d->emcy_next = 0;
		memset(d->emcy, 0, sizeof(d->emcy));
		m->s[id].unexpected_reported = false;
		m->s[id].dup_reported = false;
	}
	m->own_id_frame_reported = 0;
}

uint8_t co_manager_node_nmt_state(const co_manager *m, uint8_t node_id)
{
	const struct mgr_slave *s;
	if (node_id < 1 || node_id > 127)
		return CO_MGR_NODE_UNKNOWN;
	if (node_id == m->own_id)
		return co_nmt_get_state(m->node);
	s = &m->s[node_id];
	if (s->last_state == CO_NMT_INITIALISING)
		return CO_NMT_PRE_OPERATIONAL;
	if (s->last_state != STATE_UNKNOWN)
		return s->last_state;
	if (is_slave(m, node_id) &&
	    (s->lost || bs_state(s) == BS_FAILED || (m->boot_time_expired && !s->d.booted)))
		return CO_MGR_NODE_MISSING;
	return CO_MGR_NODE_UNKNOWN;
}
