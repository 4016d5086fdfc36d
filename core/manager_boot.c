/* SPDX-License-Identifier: MIT */
/*
 * core/manager_boot.c - the CiA 302-2 boot slave process of one node: a
 * core/fsm.h machine per node, its boot slot of the SDO client pool.
 */
#include <string.h>

#include "core/guarding.h"
#include "core/heartbeat.h"
#include "core/manager_int.h"
#include "core/nmt.h"
#include "core/sdo_client.h"

static bool chan_acquire(struct mgr_slave *s)
{
	co_manager *m = s->m;
	if (s->slot)
		return true;
	if (m->slots_used >= m->n_slots)
		return false;
	m->slots_used++;
	s->slot = true;
	return true;
}

static void chan_release(struct mgr_slave *s)
{
	if (!s->slot)
		return;
	s->slot = false;
	s->m->slots_used--;
	s->m->wake_pending = true;
}

static void sdo_con(void *arg, const co_ev_sdo_cli *c)
{
	struct mgr_slave *s = arg;
	co_manager *m = s->m;
	uint64_t now = m->node->now_us;
	uint32_t v = 0;
	struct mgr_in in = { .kind = IN_SDO, .abort = c->abort, .index = c->index, .sub = c->sub };

	if (m->destroying || !s->sdo_pending || s->tag != c->tag)
		return; /* disowned */
	s->sdo_pending = false;
	for (uint32_t i = 0; c->data && i < c->size && i < 4; i++)
		v |= (uint32_t)c->data[i] << (8 * i);
	in.value = v;
	mgr_enter(m, now);
	bs_input(s, &in, now);
	mgr_after(m, now);
}

static int sdo_read(struct mgr_slave *s, uint16_t index, uint8_t sub, uint64_t now_us)
{
	co_manager *m = s->m;
	sdo_client_req r = {
		.upload = true,
		.node_id = s->id,
		.index = index,
		.sub = sub,
		.mode = 0,
		.timeout_ms = m->cfg.sdo_timeout_ms,
		.buf = s->buf,
		.cap = sizeof(s->buf),
		.con = sdo_con,
		.con_arg = s,
	};
	int rc;

	s->gen++;
	r.tag = MGR_TAG | ((uint64_t)(s->gen & 0xFFFFFFu) << 8) | s->id;
	s->tag = r.tag;
	rc = sdo_client_pool_submit(m->node, &r, now_us);
	s->sdo_pending = rc == 0;
	return rc;
}

static uint8_t step_of_sub(uint8_t sub)
{
	return (uint8_t)(CO_MGR_STEP_VENDOR + sub - 1);
}

static char letter_of_sub(uint8_t sub)
{
	static const char l[5] = { 0, 'D', 'M', 'N', 'O' };
	return l[sub];
}

/* A failed step: report it and go to FAILED. */
static int bs_fail(struct mgr_slave *s, uint8_t step, char status, uint32_t abort, uint16_t index,
		   uint8_t sub, uint32_t value, uint32_t expected)
{
	if (strchr("CDMNO", status))
		s->mismatch = true;
	mgr_emit_boot(s, step, status, abort, index, sub, value, expected, true);
	return BS_FAILED;
}

static void bs_leave(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	(void)now_us;
	s->timer_us = CO_NO_DEADLINE;
	s->sdo_pending = false; /* disowned, see core/manager_int.h */
}

static int idle_enter(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	(void)now_us;
	chan_release(s);
	s->d.booting = false;
	return CO_FSM_STAY;
}

/* 302-2: "Is the slave in the network list (1F81h bit 0)?" No -> A. */
static int assignment_enter(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	co_manager *m = s->m;
	uint32_t a = assignment(m, s->id);

	chan_release(s);
	s->d.assignment = a;
	s->d.booting = true;
	s->d.booted = false;
	s->already_op = false;
	s->mismatch = false;
	s->d.boot_started_us = now_us;
	if (!(a & CO_MGR_1F81_SLAVE))
		return bs_fail(s, CO_MGR_STEP_ASSIGNMENT, 'A', 0, 0x1F81, s->id, a, 0);
	if (!(a & CO_MGR_1F81_BOOT))
		return BS_ERRCTRL; /* "may not be booted": supervise only */
	if ((a & CO_MGR_1F81_KEEP_ALIVE) && s->network_boot)
		return BS_KEEP_ALIVE;
	return s->wait_bootup ? BS_WAIT_BOOTUP : BS_WAIT_CHANNEL;
}

/* 302-2 keep-alive: an OPERATIONAL node is not reset (status L, the boot
 * goes on with the checks); any other state -> reset communication. */
static int keep_alive_check(struct mgr_slave *s, bool final, uint64_t now_us)
{
	co_manager *m = s->m;
	/* heartbeats only make events when the state changes: ask the
	 * consumer for what it heard last */
	if (s->last_state == STATE_UNKNOWN)
		s->last_state = co_hb_remote_state(m->node, s->id);
	if (s->last_state == CO_NMT_OPERATIONAL) {
		s->already_op = true;
		s->expected_state = CO_NMT_OPERATIONAL;
		mgr_emit_boot(s, CO_MGR_STEP_KEEP_ALIVE, 'L', 0, 0, 0, s->last_state, 0, false);
		return BS_WAIT_CHANNEL;
	}
	if (s->last_state == STATE_UNKNOWN && !final)
		return CO_FSM_STAY;
	mgr_emit_boot(s, CO_MGR_STEP_KEEP_ALIVE, 0, 0, 0, 0, s->last_state, 0, false);
	mgr_nmt_send(m, s->id, CO_NMT_CS_RESET_COMM, now_us);
	s->wait_bootup = true;
	return BS_WAIT_BOOTUP;
}

static int keep_alive_enter(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	uint32_t wait = hb_time_ms(s->m, s->id);
	if (wait < s->m->cfg.reset_wait_ms)
		wait = s->m->cfg.reset_wait_ms;
	s->timer_us = now_us + (uint64_t)wait * 1000u;
	return keep_alive_check(s, false, now_us);
}

static int keep_alive_timeout(void *obj, uint64_t now_us)
{
	return keep_alive_check(obj, true, now_us);
}

static int keep_alive_con(void *obj, const void *con, uint64_t now_us)
{
	const struct mgr_in *in = con;
	if (in->kind != IN_HB && in->kind != IN_BOOTUP)
		return CO_FSM_STAY;
	return keep_alive_check(obj, in->kind == IN_BOOTUP, now_us);
}

/* 302-2 network boot: the node was told to reset communication; its boot-up
 * (or reset_wait_ms) lets the boot go on. */
static int wait_bootup_enter(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	if (s->bootup_since_reset)
		return BS_WAIT_CHANNEL;
	s->timer_us = now_us + (uint64_t)s->m->cfg.reset_wait_ms * 1000u;
	return CO_FSM_STAY;
}

static int wait_bootup_timeout(void *obj, uint64_t now_us)
{
	(void)obj;
	(void)now_us;
	return BS_WAIT_CHANNEL;
}

static int wait_bootup_con(void *obj, const void *con, uint64_t now_us)
{
	const struct mgr_in *in = con;
	(void)obj;
	(void)now_us;
	return in->kind == IN_BOOTUP ? BS_WAIT_CHANNEL : CO_FSM_STAY;
}

static int wait_channel_enter(void *obj, uint64_t now_us)
{
	(void)now_us;
	return chan_acquire(obj) ? BS_DEVICE_TYPE : CO_FSM_STAY;
}

static int wait_channel_con(void *obj, const void *con, uint64_t now_us)
{
	const struct mgr_in *in = con;
	(void)now_us;
	if (in->kind != IN_CHANNEL)
		return CO_FSM_STAY;
	return chan_acquire(obj) ? BS_DEVICE_TYPE : CO_FSM_STAY;
}

/* 302-2 "check device type": read 1000h; no answer -> B, differs from a
 * non-zero 1F84h -> C. */
static int device_type_enter(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	int rc = sdo_read(s, 0x1000, 0, now_us);
	if (rc < 0)
		return bs_fail(s, CO_MGR_STEP_DEVICE_TYPE, 'B', SDO_AB_GENERAL, 0x1000, 0, 0, 0);
	return CO_FSM_STAY;
}

static int device_type_con(void *obj, const void *con, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	const struct mgr_in *in = con;
	uint32_t expected = od_u32(s->m, 0x1F84, s->id);
	(void)now_us;
	if (in->kind != IN_SDO)
		return CO_FSM_STAY;
	if (in->abort)
		return bs_fail(s, CO_MGR_STEP_DEVICE_TYPE, 'B', in->abort, 0x1000, 0, 0, expected);
	if (expected && in->value != expected)
		return bs_fail(s, CO_MGR_STEP_DEVICE_TYPE, 'C', 0, 0x1000, 0, in->value, expected);
	mgr_emit_boot(s, CO_MGR_STEP_DEVICE_TYPE, 0, 0, 0x1000, 0, in->value, expected, false);
	s->id_sub = 1;
	return BS_IDENTITY;
}

/* 302-2 "check identification": 1018h:k only where 1F85h+k-1 != 0; any
 * failure (abort or other value) -> D, M, N or O. */
static int identity_enter(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	while (s->id_sub <= 4 && !od_u32(s->m, (uint16_t)(0x1F84 + s->id_sub), s->id))
		s->id_sub++;
	if (s->id_sub > 4)
		return BS_SOFTWARE;
	if (sdo_read(s, 0x1018, s->id_sub, now_us) < 0)
		return bs_fail(s, step_of_sub(s->id_sub), letter_of_sub(s->id_sub), SDO_AB_GENERAL,
			       0x1018, s->id_sub, 0, 0);
	return CO_FSM_STAY;
}

static int identity_con(void *obj, const void *con, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	const struct mgr_in *in = con;
	uint8_t k = s->id_sub;
	uint32_t expected = od_u32(s->m, (uint16_t)(0x1F84 + k), s->id);
	(void)now_us;
	if (in->kind != IN_SDO)
		return CO_FSM_STAY;
	if (in->abort || in->value != expected)
		return bs_fail(s, step_of_sub(k), letter_of_sub(k), in->abort, 0x1018, k,
			       in->abort ? 0 : in->value, expected);
	mgr_emit_boot(s, step_of_sub(k), 0, 0, 0x1018, k, in->value, expected, false);
	s->id_sub++;
	return BS_IDENTITY; /* re-entered: next sub */
}

/* 302-2 "check software" (1F81h bit 5): the CiA 302-3 software manager
 * hook; without it there is nothing to do. Failures are G, H or I. */
static int software_enter(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	co_manager *m = s->m;
	int rc = 0;
	if (m->cfg.software)
		rc = m->cfg.software(m->cfg.software_ctx, s->id, now_us);
	if (rc == 1)
		return CO_FSM_STAY;
	if (rc < 0)
		return bs_fail(s, CO_MGR_STEP_SOFTWARE, 'G', 0, 0x1F55, s->id, (uint32_t)-rc, 0);
	if (m->cfg.software && (assignment(m, s->id) & CO_MGR_1F81_VERIFY_SW))
		mgr_emit_boot(s, CO_MGR_STEP_SOFTWARE, 0, 0, 0, 0, 0, 0, false);
	return BS_CONFIGURE;
}

static int software_con(void *obj, const void *con, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	const struct mgr_in *in = con;
	(void)now_us;
	if (in->kind != IN_SOFTWARE)
		return CO_FSM_STAY;
	if (in->value)
		return bs_fail(s, CO_MGR_STEP_SOFTWARE, (char)in->value, in->abort, in->index,
			       in->sub, in->found, 0);
	/* passed; index:sub = value is what the software manager saw (its
	 * program state, 1F51h:1, when the software is not checked) */
	mgr_emit_boot(s, CO_MGR_STEP_SOFTWARE, 0, 0, in->index, in->sub, in->found, 0, false);
	return BS_CONFIGURE;
}

/* 302-2 "check and update configuration": the CiA 302-3 hook; without it
 * there is nothing to do. A failure is J. */
static int configure_enter(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	co_manager *m = s->m;
	int rc = 0;
	if (m->cfg.configure)
		rc = m->cfg.configure(m->cfg.configure_ctx, s->id, now_us);
	if (rc == 1)
		return CO_FSM_STAY;
	if (rc < 0) /* 1F22h:n is no concise DCF (or the node's job is busy):
		     * J on that object, no entry of it was written (value 0) */
		return bs_fail(s, CO_MGR_STEP_CONFIGURE, 'J', SDO_AB_GENERAL, 0x1F22, s->id, 0, 0);
	mgr_emit_boot(s, CO_MGR_STEP_CONFIGURE, 0, 0, 0, 0, 0, 0, false);
	return BS_PDO_LAYOUT;
}

static int configure_con(void *obj, const void *con, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	const struct mgr_in *in = con;
	(void)now_us;
	if (in->kind != IN_CONFIGURED)
		return CO_FSM_STAY;
	/* value: the concise DCF entry that failed, or the entries written */
	if (in->abort)
		return bs_fail(s, CO_MGR_STEP_CONFIGURE, 'J', in->abort, in->index, in->sub,
			       in->value, 0);
	mgr_emit_boot(s, CO_MGR_STEP_CONFIGURE, 0, 0, 0, 0, in->value, 0, false);
	return BS_PDO_LAYOUT;
}

/* The slave's PDO layout (core/pdo_scan.h), read after the configure step
 * so that it is the configured one. Not a CiA 302-2 check: a layout that
 * cannot be learnt is reported (abort, object) and the boot goes on. */
static int pdo_layout_enter(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	co_manager *m = s->m;
	int rc = 0;
	if (m->cfg.pdo_layout)
		rc = m->cfg.pdo_layout(m->cfg.pdo_layout_ctx, s->id, now_us);
	if (rc == 1)
		return CO_FSM_STAY;
	if (rc < 0) /* not even started: the client pool is full or busy */
		mgr_emit_boot(s, CO_MGR_STEP_PDO_LAYOUT, 0, SDO_AB_NO_RESOURCE, 0x1800, 1, 0, 0,
			      false);
	return BS_ERRCTRL;
}

static int pdo_layout_con(void *obj, const void *con, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	const struct mgr_in *in = con;
	(void)now_us;
	if (in->kind != IN_PDO_LAYOUT)
		return CO_FSM_STAY;
	/* value: PDOs kept, TPDOs | RPDOs << 16; expected: those dropped */
	mgr_emit_boot(s, CO_MGR_STEP_PDO_LAYOUT, 0, in->abort, in->index, in->sub, in->value,
		      in->found, false);
	return BS_ERRCTRL;
}

/* 302-2 "start error control service": a heartbeat consumer (1016h) must
 * see a heartbeat within its time (else K); else node guarding with the
 * 1F81h guard time and retry factor must get an answer within the life
 * time (else F); else nothing to start. */
static int errctrl_enter(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	co_manager *m = s->m;
	uint32_t a = assignment(m, s->id);
	uint16_t hb = hb_time_ms(m, s->id);
	uint32_t gt = CO_MGR_1F81_GUARD_MS(a), lf = CO_MGR_1F81_RETRY_FACTOR(a);

	chan_release(s);
	if (hb) {
		if (co_hb_consumer_status(m->node, s->id) == CO_HB_MON_ACTIVE)
			goto passed;
		s->timer_us = now_us + (uint64_t)hb * 1000u;
		return CO_FSM_STAY;
	}
	if (gt) {
		if (co_guard_master_add(m->node, s->id, (uint16_t)gt, (uint8_t)lf, now_us) < 0)
			return bs_fail(s, CO_MGR_STEP_ERRCTRL, 'F', 0, 0x1F81, s->id, a, 0);
		s->timer_us = now_us + (uint64_t)gt * (lf ? lf : 1) * 1000u;
		return CO_FSM_STAY;
	}
passed:
	mgr_emit_boot(s, CO_MGR_STEP_ERRCTRL, 0, 0, hb ? 0x1016 : 0, 0, hb, 0, false);
	return BS_START;
}

static int errctrl_con(void *obj, const void *con, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	const struct mgr_in *in = con;
	uint16_t hb = hb_time_ms(s->m, s->id);
	(void)now_us;
	if (in->kind != IN_HB || (!hb && !in->guarded))
		return CO_FSM_STAY;
	mgr_emit_boot(s, CO_MGR_STEP_ERRCTRL, 0, 0, hb ? 0x1016 : 0x1F81, hb ? 0 : s->id, hb, 0,
		      false);
	return BS_START;
}

static int errctrl_timeout(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	uint16_t hb = hb_time_ms(s->m, s->id);
	(void)now_us;
	if (hb)
		return bs_fail(s, CO_MGR_STEP_ERRCTRL, 'K', 0, 0x1016, 0, hb, 0);
	(void)co_guard_master_remove(s->m->node, s->id);
	return bs_fail(s, CO_MGR_STEP_ERRCTRL, 'F', 0, 0x1F81, s->id, assignment(s->m, s->id), 0);
}

/* 302-2 "start slave": individually once the network runs (1F80h bit 3
 * clear, or the application started the network itself); before that the
 * network start sends it (bit 1: one broadcast). */
static int start_enter(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	co_manager *m = s->m;
	bool app = f80(m) & CO_MGR_1F80_APP_STARTS_SLAVES;
	bool sent = false;

	if (co_fsm_state_of(&m->fsm) == CO_MGR_STOPPED) {
		/* the network is stopped: so is a node booted meanwhile */
		mgr_nmt_send(m, s->id, CO_NMT_CS_STOP, now_us);
	} else if (!s->already_op && m->net_started && (!app || m->net_started_explicit)) {
		/* its configured state: OPERATIONAL unless told otherwise */
		if (s->target_state == CO_NMT_OPERATIONAL)
			mgr_nmt_send(m, s->id, CO_NMT_CS_START, now_us);
		else if (s->target_state == CO_NMT_STOPPED)
			mgr_nmt_send(m, s->id, CO_NMT_CS_STOP, now_us);
		sent = s->target_state == CO_NMT_OPERATIONAL;
	}
	s->d.booted = true;
	s->d.booting = false;
	s->d.boot_count++;
	s->d.boot_time_us = now_us - s->d.boot_started_us;
	s->d.status = 0;
	s->d.abort = 0;
	s->last_fail = 0;
	s->attempted = true;
	s->ever_booted = true;
	s->lost = false;
	m->check_pending = true;
	mgr_emit_boot(s, CO_MGR_STEP_START, 0, 0, 0, 0, sent, 0, true);
	return BS_BOOTED;
}

/* Retry a node that did not answer: optional ones at retry_ms for ever,
 * mandatory ones until 1F89h ran out (then the scan looks for them).
 * Identity mismatches wait for a boot-up or an explicit request. */
static int failed_enter(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	co_manager *m = s->m;
	bool retryable = s->d.status && strchr("BFK", s->d.status);

	chan_release(s);
	s->d.booting = false;
	s->attempted = true;
	m->check_pending = true;
	if (retryable && m->cfg.retry_ms && (!is_mandatory(m, s->id) || !m->boot_time_expired))
		s->timer_us = now_us + (uint64_t)m->cfg.retry_ms * 1000u;
	return CO_FSM_STAY;
}

static int failed_timeout(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	(void)now_us;
	s->network_boot = false;
	s->wait_bootup = false;
	return BS_ASSIGNMENT;
}

static const co_fsm_state bs_states[BS_COUNT] = {
	[BS_IDLE] = { .name = "idle", .on_enter = idle_enter, .on_leave = bs_leave },
	[BS_ASSIGNMENT] = { .name = "assignment",
			    .on_enter = assignment_enter,
			    .on_leave = bs_leave },
	[BS_KEEP_ALIVE] = { .name = "keep-alive",
			    .on_enter = keep_alive_enter,
			    .on_timeout = keep_alive_timeout,
			    .on_con = keep_alive_con,
			    .on_leave = bs_leave },
	[BS_WAIT_BOOTUP] = { .name = "wait-boot-up",
			     .on_enter = wait_bootup_enter,
			     .on_timeout = wait_bootup_timeout,
			     .on_con = wait_bootup_con,
			     .on_leave = bs_leave },
	[BS_WAIT_CHANNEL] = { .name = "wait-channel",
			      .on_enter = wait_channel_enter,
			      .on_con = wait_channel_con,
			      .on_leave = bs_leave },
	[BS_DEVICE_TYPE] = { .name = "device-type",
			     .on_enter = device_type_enter,
			     .on_con = device_type_con,
			     .on_leave = bs_leave },
	[BS_IDENTITY] = { .name = "identity",
			  .on_enter = identity_enter,
			  .on_con = identity_con,
			  .on_leave = bs_leave },
	[BS_SOFTWARE] = { .name = "software",
			  .on_enter = software_enter,
			  .on_con = software_con,
			  .on_leave = bs_leave },
	[BS_CONFIGURE] = { .name = "configure",
			   .on_enter = configure_enter,
			   .on_con = configure_con,
			   .on_leave = bs_leave },
	[BS_PDO_LAYOUT] = { .name = "pdo-layout",
			    .on_enter = pdo_layout_enter,
			    .on_con = pdo_layout_con,
			    .on_leave = bs_leave },
	[BS_ERRCTRL] = { .name = "error-control",
			 .on_enter = errctrl_enter,
			 .on_timeout = errctrl_timeout,
			 .on_con = errctrl_con,
			 .on_leave = bs_leave },
	[BS_START] = { .name = "start", .on_enter = start_enter, .on_leave = bs_leave },
	[BS_BOOTED] = { .name = "booted", .on_leave = bs_leave },
	[BS_FAILED] = { .name = "failed",
			.on_enter = failed_enter,
			.on_timeout = failed_timeout,
			.on_leave = bs_leave },
};

const co_fsm_def mgr_boot_def = { "boot-slave", bs_states, BS_COUNT };

/* No SDO in a stopped network (CiA 301 §7.3.2.2: a node in STOPPED takes
 * part in NMT and error control only): while the line is STOPPED a boot
 * slave process does not run; the node is held stopped and booted when
 * the network leaves STOPPED (mgr_boot_deferred_nodes). True if it was held. */
bool mgr_boot_hold_stopped(struct mgr_slave *s, uint64_t now_us)
{
	co_manager *m = s->m;
	if (co_fsm_state_of(&m->fsm) != CO_MGR_STOPPED)
		return false;
	co_fsm_goto(&s->fsm, BS_IDLE, now_us);
	s->d.booted = false;
	s->boot_deferred = true;
	if (s->expected_state != CO_NMT_STOPPED)
		mgr_nmt_send(m, s->id, CO_NMT_CS_STOP, now_us);
	return true;
}

/* Start (or restart) the boot slave process of one node. */
void mgr_boot_begin(struct mgr_slave *s, bool network_boot, bool wait_bootup, uint64_t now_us)
{
	if (mgr_boot_hold_stopped(s, now_us))
		return;
	s->network_boot = network_boot;
	s->wait_bootup = wait_bootup;
	co_fsm_goto(&s->fsm, BS_ASSIGNMENT, now_us);
}
