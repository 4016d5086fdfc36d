/* SPDX-License-Identifier: MIT */
/*
 * The CiA 302-2 manager of one line: NMT start-up (1F80h), the network
 * boot, one boot slave process per node (1F81h, 1F84h..1F89h), error
 * control supervision, Request NMT (1F82h), configuration request (1F25h)
 * and the diagnostics of the line.
 *
 * Why the boot runs in parallel: the reference manuals boot node 1, then
 * node 2, ...; a silent node then costs every node behind it one SDO
 * timeout. Here every assigned node runs its own machine and only the SDO
 * client pool bounds how many talk at once (a node holds one "boot slot"
 * from its 1000h read to the end of the configure step; there are as many
 * slots as client channels, so the pool's FIFO never overflows because of
 * the boot).
 *
 * A boot that restarts while its SDO request runs does not cancel it: it
 * disowns it (the confirmation is ignored). The pool runs requests to one
 * server in submission order, so the next request of that node starts
 * only after the old answer or timeout; a cancel would leave the old
 * answer on the bus to be taken for the answer of the next request.
 *
 * Re-entrancy: the core delivers events synchronously, and the manager's
 * own calls (SDO cancel, NMT send) may produce events. Every entry point
 * therefore only feeds inputs to machines; the work that looks at the
 * whole line (waking nodes that wait for a channel, the network start
 * decision, state/flag reports) runs once at the end of the outermost
 * entry (mgr_after), never from inside a machine handler.
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/co_internal.h"
#include "core/fsm.h"
#include "core/guarding.h"
#include "core/heartbeat.h"
#include "core/manager.h"
#include "core/nmt.h"
#include "core/od.h"
#include "core/sdo_client.h"

#define MGR_TAG 0x4D47520000000000ull /* "MGR" in the top bytes */
#define MGR_TAG_MASK 0xFFFFFF0000000000ull
#define STATE_UNKNOWN 0xFFu

/* ---- boot slave process: states ------------------------------------------ */

enum bs_state {
	BS_IDLE = 0,     /* not booting */
	BS_ASSIGNMENT,   /* 302-2 boot slave: "slave in network list (1F81h)?" */
	BS_KEEP_ALIVE,   /* 302-2: keep-alive bit set -> NMT state check */
	BS_WAIT_BOOTUP,  /* 302-2 network boot: after reset communication */
	BS_WAIT_CHANNEL, /* waits for a boot slot (SDO client pool) */
	BS_DEVICE_TYPE,  /* 302-2: "check device type" 1000h vs 1F84h */
	BS_IDENTITY,     /* 302-2: "check identification" 1018h:1..4 vs
	                  * 1F85h..1F88h */
	BS_CONFIGURE,    /* 302-2: "check and update configuration" (302-3) */
	BS_ERRCTRL,      /* 302-2: "start error control service" */
	BS_START,        /* 302-2: "start slave" per 1F80h */
	BS_BOOTED,       /* 302-2: boot slave process finished, supervised */
	BS_FAILED,       /* 302-2: error status A..O; retry per retry_ms */
	BS_SOFTWARE,     /* 302-2: "check software" (302-3 software manager),
	                  * between BS_IDENTITY and BS_CONFIGURE */
	BS_COUNT
};

enum in_kind {
	IN_SDO,
	IN_BOOTUP,
	IN_HB,
	IN_CHANNEL,
	IN_CONFIGURED,
	IN_SOFTWARE
};

struct mgr_in {
	enum in_kind kind;
	uint32_t abort;
	uint32_t value;
	uint16_t index;
	uint8_t sub;
	bool guarded; /* IN_HB: seen through node guarding */
};

struct mgr_slave {
	co_manager *m;
	uint8_t id;
	co_fsm fsm;
	uint64_t timer_us;
	bool slot; /* holds a boot slot */
	bool sdo_pending;
	uint64_t tag; /* of the pending SDO request */
	uint32_t gen; /* bumps when a pending request is disowned */
	uint8_t buf[4];
	uint8_t id_sub;    /* 1018h sub being checked (1..4) */
	bool network_boot; /* this boot is part of the network boot */
	bool wait_bootup;  /* reset communication was sent: wait */
	bool already_op;   /* keep-alive node found OPERATIONAL (L) */
	bool attempted;    /* a boot attempt ended since the network boot */
	bool ever_booted;  /* booted since the network boot began */
	bool keep_op;
	uint8_t target_state; /* NMT state after its boot (CO_NMT_OPERATIONAL,
	                       * PRE_OPERATIONAL or STOPPED) */
	bool boot_deferred;   /* boot-up while the network was stopped: booted
	                       * when the network leaves STOPPED */
	bool lost;            /* error control lost after boot */
	bool unexpected_reported;
	bool dup_reported;
	bool mismatch;         /* identity wrong (C, D, M, N, O) */
	bool cmd_since_bootup; /* the manager sent it an NMT command */
	bool emcy_active;
	uint8_t last_state;      /* NMT state last heard (HB, guarding, boot-up) */
	uint8_t expected_state;  /* last state the manager commanded */
	uint64_t bootup_us;      /* last boot-up heard (0 = none) */
	bool bootup_since_reset; /* a boot-up came after our last reset */
	char last_fail;          /* letter of the last reported failure */
	uint8_t last_fail_step;
	uint32_t last_fail_abort;
	co_mgr_node_diag d;
};

struct co_manager {
	co_node *node;
	co_od *od;
	co_manager_config cfg;
	co_fsm fsm;
	uint8_t own_id;
	uint8_t reset_cs;         /* NMT command of the next network reset */
	uint64_t timer_us;        /* end of the boot time, 1F89h */
	uint64_t boot_started_us; /* the network boot began (1F89h counts) */
	uint64_t scan_us;         /* next scan for missing nodes */
	bool autostart_pending;
	bool boot_time_expired;
	bool awaiting_mandatory; /* BOOTED because 1F89h ran out */
	bool net_started;
	bool net_started_explicit;
	bool own_id_reported;
	bool wake_pending;
	bool check_pending;
	int depth;
	uint8_t reported_state, reported_flags;
	bool reported_once;
	int rx[3];
	uint8_t n_slots, slots_used;
	bool destroying;
	co_mgr_diag cnt;         /* counters and first error (bit lists unused) */
	struct mgr_slave s[128]; /* by node-ID, [0] unused */
};

static const co_fsm_def bs_def;
static const co_fsm_def mgr_def;
static void bs_input(struct mgr_slave *s, const struct mgr_in *in, uint64_t now_us);
static void mgr_enter(co_manager *m, uint64_t now_us);
static void mgr_after(co_manager *m, uint64_t now_us);

/* ---- names ------------------------------------------------------------------- */

const char *co_mgr_state_to_string(uint8_t state)
{
	static const char *const n[CO_MGR_STATE_COUNT] = {
		"slave",       "resetting", "booting",         "wait-mandatory", "booted",
		"operational", "stopped",   "pre-operational", "fatal",
	};
	return state < CO_MGR_STATE_COUNT ? n[state] : "?";
}

const char *co_mgr_step_to_string(uint8_t step)
{
	static const char *const n[CO_MGR_STEP_COUNT] = {
		"assignment",    "keep-alive", "device-type", "vendor-id",
		"product-code",  "revision",   "serial",      "configure",
		"error-control", "start",      "boot-time",   "software",
	};
	return step < CO_MGR_STEP_COUNT ? n[step] : "?";
}

const char *co_mgr_status_to_string(char status)
{
	switch (status) {
	case 0:
		return "ok";
	case 'A':
		return "not in the network list (1F81h)";
	case 'B':
		return "no answer to the read of 1000h";
	case 'C':
		return "device type differs from 1F84h";
	case 'D':
		return "vendor-ID differs from 1F85h";
	case 'E':
		return "heartbeat event";
	case 'F':
		return "node guarding event";
	case 'G':
		return "program download objects not configured";
	case 'H':
		return "software update required but not allowed";
	case 'I':
		return "program download failed";
	case 'J':
		return "configuration download failed";
	case 'K':
		return "no heartbeat during the start of error control";
	case 'L':
		return "slave was operational already (keep-alive)";
	case 'M':
		return "product code differs from 1F86h";
	case 'N':
		return "revision number differs from 1F87h";
	case 'O':
		return "serial number differs from 1F88h";
	}
	return "?";
}

const char *co_mgr_node_what_to_string(uint8_t what)
{
	static const char *const n[CO_MGR_NODE_WHAT_COUNT] = {
		"unexpected",  "late",    "lost",        "back",           "duplicate", "own-id",
		"nmt-ignored", "keep-op", "request-nmt", "error-reaction", "program",
	};
	return what < CO_MGR_NODE_WHAT_COUNT ? n[what] : "?";
}

/* ---- OD access ------------------------------------------------------------------ */

static uint32_t od_u32(const co_manager *m, uint16_t index, uint8_t sub)
{
	uint32_t v = 0;
	(void)co_od_get_u32(m->od, index, sub, &v);
	return v;
}

static uint32_t f80(const co_manager *m)
{
	return od_u32(m, 0x1F80, 0);
}

static uint32_t assignment(const co_manager *m, uint8_t id)
{
	return id >= 1 && id <= 127 ? od_u32(m, 0x1F81, id) : 0;
}

static bool is_slave(const co_manager *m, uint8_t id)
{
	return assignment(m, id) & CO_MGR_1F81_SLAVE;
}

static bool is_mandatory(const co_manager *m, uint8_t id)
{
	uint32_t a = assignment(m, id);
	return (a & CO_MGR_1F81_SLAVE) && (a & CO_MGR_1F81_MANDATORY);
}

/* Nodes the manager boots: assigned as slave with "may be booted". */
static bool is_bootable(const co_manager *m, uint8_t id)
{
	uint32_t a = assignment(m, id);
	return (a & CO_MGR_1F81_SLAVE) && (a & CO_MGR_1F81_BOOT);
}

/* Heartbeat consumer time for `id` from 1016h (0 = not monitored). */
static uint16_t hb_time_ms(const co_manager *m, uint8_t id)
{
	uint8_t n = 0;
	if (co_od_get_u8(m->od, 0x1016, 0, &n) < 0)
		return 0;
	for (uint8_t sub = 1; sub && sub <= n; sub++) {
		uint32_t v = od_u32(m, 0x1016, sub);
		if (((v >> 16) & 0xFF) == id && (v & 0xFFFF))
			return (uint16_t)(v & 0xFFFF);
	}
	return 0;
}

static bool is_master(const co_manager *m)
{
	return f80(m) & CO_MGR_1F80_MASTER;
}

/* ---- events -------------------------------------------------------------------- */

static uint8_t compute_flags(const co_manager *m);

static void emit(co_manager *m, co_event_kind kind, const co_ev_mgr *e)
{
	co_event ev = { .kind = kind };
	ev.u.mgr = *e;
	co_node_emit(m->node, &ev);
}

static void note_first_error(co_manager *m, uint8_t id, char status, uint32_t code)
{
	if (m->cnt.first_error_node)
		return;
	m->cnt.first_error_node = id;
	m->cnt.first_error_status = status;
	m->cnt.first_error_code = code;
}

static void emit_node(co_manager *m, uint8_t id, uint8_t what, uint32_t value)
{
	co_ev_mgr e = {
		.node = id, .what = what, .value = value, .mandatory = is_mandatory(m, id)
	};
	emit(m, CO_EV_MGR_NODE, &e);
}

/* One step of a boot slave process: status 0 = passed. Failures that
 * repeat the previous one exactly (a node retried every second) are counted
 * but not reported again. */
static void emit_boot(struct mgr_slave *s, uint8_t step, char status, uint32_t abort,
		      uint16_t index, uint8_t sub, uint32_t value, uint32_t expected, bool done)
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
		note_first_error(m, s->id, status, abort);
		e.flags = compute_flags(m);
		emit(m, CO_EV_MGR_BOOT, &e);
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
		note_first_error(m, s->id, status, abort);
		s->last_fail = status;
		s->last_fail_step = step;
		s->last_fail_abort = abort;
		if (repeat)
			return;
	}
	e.flags = compute_flags(m);
	emit(m, CO_EV_MGR_BOOT, &e);
}

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

static void nmt_send(co_manager *m, uint8_t target, uint8_t cs, uint64_t now_us)
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

/* ---- SDO: boot slots and the pool ------------------------------------------ */

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

/* ---- boot slave process: handlers ---------------------------------------------- */

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
	emit_boot(s, step, status, abort, index, sub, value, expected, true);
	return BS_FAILED;
}

static void bs_leave(void *obj, uint64_t now_us)
{
	struct mgr_slave *s = obj;
	(void)now_us;
	s->timer_us = CO_NO_DEADLINE;
	s->sdo_pending = false; /* disowned, see the file comment */
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
		emit_boot(s, CO_MGR_STEP_KEEP_ALIVE, 'L', 0, 0, 0, s->last_state, 0, false);
		return BS_WAIT_CHANNEL;
	}
	if (s->last_state == STATE_UNKNOWN && !final)
		return CO_FSM_STAY;
	emit_boot(s, CO_MGR_STEP_KEEP_ALIVE, 0, 0, 0, 0, s->last_state, 0, false);
	nmt_send(m, s->id, CO_NMT_CS_RESET_COMM, now_us);
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
	emit_boot(s, CO_MGR_STEP_DEVICE_TYPE, 0, 0, 0x1000, 0, in->value, expected, false);
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
	emit_boot(s, step_of_sub(k), 0, 0, 0x1018, k, in->value, expected, false);
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
		emit_boot(s, CO_MGR_STEP_SOFTWARE, 0, 0, 0, 0, 0, 0, false);
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
			       in->sub, 0, 0);
	emit_boot(s, CO_MGR_STEP_SOFTWARE, 0, 0, 0, 0, 0, 0, false);
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
	emit_boot(s, CO_MGR_STEP_CONFIGURE, 0, 0, 0, 0, 0, 0, false);
	return BS_ERRCTRL;
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
	emit_boot(s, CO_MGR_STEP_CONFIGURE, 0, 0, 0, 0, in->value, 0, false);
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
	emit_boot(s, CO_MGR_STEP_ERRCTRL, 0, 0, hb ? 0x1016 : 0, 0, hb, 0, false);
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
	emit_boot(s, CO_MGR_STEP_ERRCTRL, 0, 0, hb ? 0x1016 : 0x1F81, hb ? 0 : s->id, hb, 0, false);
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
		nmt_send(m, s->id, CO_NMT_CS_STOP, now_us);
	} else if (!s->already_op && m->net_started && (!app || m->net_started_explicit)) {
		/* its configured state: OPERATIONAL unless told otherwise */
		if (s->target_state == CO_NMT_OPERATIONAL)
			nmt_send(m, s->id, CO_NMT_CS_START, now_us);
		else if (s->target_state == CO_NMT_STOPPED)
			nmt_send(m, s->id, CO_NMT_CS_STOP, now_us);
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
	emit_boot(s, CO_MGR_STEP_START, 0, 0, 0, 0, sent, 0, true);
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
static const co_fsm_def bs_def = { "boot-slave", bs_states, BS_COUNT };

static int bs_state(const struct mgr_slave *s)
{
	return co_fsm_state_of(&s->fsm);
}

static bool bs_running(const struct mgr_slave *s)
{
	int st = bs_state(s);
	return st != BS_IDLE && st != BS_BOOTED && st != BS_FAILED;
}

static void bs_input(struct mgr_slave *s, const struct mgr_in *in, uint64_t now_us)
{
	co_fsm_con(&s->fsm, in, now_us);
}

/* Start (or restart) the boot slave process of one node. */
static void bs_begin(struct mgr_slave *s, bool network_boot, bool wait_bootup, uint64_t now_us)
{
	s->network_boot = network_boot;
	s->wait_bootup = wait_bootup;
	co_fsm_goto(&s->fsm, BS_ASSIGNMENT, now_us);
}

/* ---- line state -------------------------------------------------------------------- */

static bool all_mandatory_booted(const co_manager *m)
{
	for (unsigned id = 1; id <= 127; id++)
		if (is_mandatory(m, (uint8_t)id) && !m->s[id].d.booted)
			return false;
	return true;
}

static uint8_t compute_flags(const co_manager *m)
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

static void report_state(co_manager *m)
{
	uint8_t st = (uint8_t)co_fsm_state_of(&m->fsm);
	uint8_t fl = compute_flags(m);
	co_ev_mgr e = { .state = st, .prev = m->reported_state, .flags = fl };

	if (m->reported_once && st == m->reported_state && fl == m->reported_flags)
		return;
	m->reported_once = true;
	m->reported_state = st;
	m->reported_flags = fl;
	emit(m, CO_EV_MGR_STATE, &e);
}

/* Start the manager and the slaves (302-2 "NMT start of the network"):
 * one broadcast when 1F80h bit 1 asks for it and every assigned node has
 * booted (a broadcast would otherwise start a wrong device too), else one
 * command per booted node. */
static void start_network_now(co_manager *m, bool explicit, uint64_t now_us)
{
	bool all = true;

	if (co_nmt_get_state(m->node) != CO_NMT_OPERATIONAL)
		(void)co_nmt_local_cmd(m->node, CO_NMT_CS_START, now_us);
	for (unsigned id = 1; id <= 127; id++)
		if (is_bootable(m, (uint8_t)id) &&
		    (!m->s[id].d.booted || m->s[id].target_state != CO_NMT_OPERATIONAL))
			all = false;
	if ((f80(m) & CO_MGR_1F80_START_ALL) && all) {
		nmt_send(m, 0, CO_NMT_CS_START, now_us);
	} else {
		for (unsigned id = 1; id <= 127; id++) {
			struct mgr_slave *s = &m->s[id];
			if (!s->d.booted || s->expected_state == s->target_state)
				continue;
			if (s->target_state == CO_NMT_OPERATIONAL)
				nmt_send(m, (uint8_t)id, CO_NMT_CS_START, now_us);
			else if (s->target_state == CO_NMT_STOPPED)
				nmt_send(m, (uint8_t)id, CO_NMT_CS_STOP, now_us);
		}
	}
	m->net_started = true;
	m->net_started_explicit = explicit;
	co_fsm_goto(&m->fsm, CO_MGR_OPERATIONAL, now_us);
}

/* The whole-line decisions, after every input (see the file comment). */
static void mgr_check(co_manager *m, uint64_t now_us)
{
	uint8_t st = (uint8_t)co_fsm_state_of(&m->fsm);
	uint32_t b80 = f80(m);
	bool all_attempted = true;

	if (st != CO_MGR_BOOTING && st != CO_MGR_WAIT_MANDATORY &&
	    !(st == CO_MGR_BOOTED && m->awaiting_mandatory))
		return;
	for (unsigned id = 1; id <= 127; id++) {
		const struct mgr_slave *s = &m->s[id];
		if (is_bootable(m, (uint8_t)id) && !s->attempted && !s->d.booted &&
		    ((b80 & CO_MGR_1F80_START_ALL) || is_mandatory(m, (uint8_t)id)))
			all_attempted = false;
	}
	if (all_mandatory_booted(m) && (all_attempted || st != CO_MGR_BOOTING)) {
		m->awaiting_mandatory = false;
		if (b80 & (CO_MGR_1F80_NO_SELF_START | CO_MGR_1F80_APP_STARTS_SLAVES)) {
			if (st != CO_MGR_BOOTED)
				co_fsm_goto(&m->fsm, CO_MGR_BOOTED, now_us);
		} else {
			start_network_now(m, false, now_us);
		}
		return;
	}
	if (st == CO_MGR_BOOTING && all_attempted)
		co_fsm_goto(&m->fsm, CO_MGR_WAIT_MANDATORY, now_us);
}

static void wake_waiting(co_manager *m, uint64_t now_us)
{
	struct mgr_in in = { .kind = IN_CHANNEL };
	/* mandatory slaves first (seed 001 §2.1, late nodes), then by ID */
	for (int pass = 0; pass < 2; pass++)
		for (unsigned id = 1; id <= 127; id++) {
			struct mgr_slave *s = &m->s[id];
			if (bs_state(s) == BS_WAIT_CHANNEL &&
			    is_mandatory(m, (uint8_t)id) == (pass == 0))
				bs_input(s, &in, now_us);
		}
}

static void mgr_enter(co_manager *m, uint64_t now_us)
{
	if (now_us > m->node->now_us)
		m->node->now_us = now_us;
	m->depth++;
}

static void mgr_after(co_manager *m, uint64_t now_us)
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
			mgr_check(m, now_us);
		}
	}
	report_state(m);
	m->depth--;
}

/* ---- line machine: handlers -------------------------------------------------------- */

static int m_slave_enter(void *obj, uint64_t now_us)
{
	co_manager *m = obj;
	report_state(m);
	m->net_started = false;
	m->timer_us = CO_NO_DEADLINE;
	/* seed 001 §2.2 transition 2: a plain slave starts itself unless 1F80h
	 * bit 2 says not to */
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

	report_state(m);
	m->reset_cs = 0;
	m->cnt.network_boots++;
	m->net_started = false;
	m->net_started_explicit = false;
	m->boot_time_expired = false;
	m->awaiting_mandatory = false;
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
		nmt_send(m, 0, cs, now_us);
	} else {
		for (unsigned id = 1; id <= 127; id++)
			if (is_slave(m, (uint8_t)id) &&
			    !(assignment(m, (uint8_t)id) & CO_MGR_1F81_KEEP_ALIVE))
				nmt_send(m, (uint8_t)id, cs, now_us);
	}
	return CO_MGR_BOOTING;
}

/* 302-2: "boot slave process" for every assigned slave, in parallel; the
 * boot time (1F89h) starts here. */
static int m_booting_enter(void *obj, uint64_t now_us)
{
	co_manager *m = obj;
	uint32_t bt = od_u32(m, 0x1F89, 0);

	report_state(m);
	m->boot_started_us = now_us;
	m->timer_us = bt ? now_us + (uint64_t)bt * 1000u : CO_NO_DEADLINE;
	for (unsigned id = 1; id <= 127; id++) {
		struct mgr_slave *s = &m->s[id];
		uint32_t a = assignment(m, (uint8_t)id);
		if (!(a & CO_MGR_1F81_SLAVE))
			continue;
		bs_begin(s, true, !(a & CO_MGR_1F81_KEEP_ALIVE), now_us);
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
		emit_boot(s, CO_MGR_STEP_BOOT_TIME, s->d.status ? s->d.status : 'B', s->d.abort,
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
	report_state(m);
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
	report_state(m);
	m->timer_us = CO_NO_DEADLINE;
	return CO_FSM_STAY;
}

/* 302-2: first pass over, mandatory slaves still missing; they are
 * retried until the boot time (1F89h) runs out */
static int m_wait_enter(void *obj, uint64_t now_us)
{
	(void)now_us;
	report_state(obj);
	return CO_FSM_STAY;
}

static const co_fsm_state mgr_states[CO_MGR_STATE_COUNT] = {
	[CO_MGR_SLAVE] = { .name = "slave", .on_enter = m_slave_enter },
	[CO_MGR_RESETTING] = { .name = "resetting", .on_enter = m_resetting_enter },
	[CO_MGR_BOOTING] = { .name = "booting",
			     .on_enter = m_booting_enter,
			     .on_timeout = m_boot_time_out },
	[CO_MGR_WAIT_MANDATORY] = { .name = "wait-mandatory",
				    .on_enter = m_wait_enter,
				    .on_timeout = m_boot_time_out },
	[CO_MGR_BOOTED] = { .name = "booted", .on_enter = m_net_enter },
	[CO_MGR_OPERATIONAL] = { .name = "operational", .on_enter = m_net_enter },
	[CO_MGR_STOPPED] = { .name = "stopped", .on_enter = m_net_enter },
	[CO_MGR_PREOP] = { .name = "pre-operational", .on_enter = m_net_enter },
	[CO_MGR_FATAL] = { .name = "fatal", .on_enter = m_fatal_enter },
};
static const co_fsm_def mgr_def = { "manager", mgr_states, CO_MGR_STATE_COUNT };

/* ---- inputs from the core ----------------------------------------------------------- */

static bool mgr_active(const co_manager *m)
{
	uint8_t st = (uint8_t)co_fsm_state_of(&m->fsm);
	return st != CO_MGR_SLAVE && st != CO_MGR_FATAL;
}

/* A node answers on the manager's own node-ID: fatal for this line. */
static void own_id_conflict(co_manager *m, uint64_t now_us)
{
	if (!is_master(m) || co_fsm_state_of(&m->fsm) == CO_MGR_FATAL)
		return;
	if (!m->own_id_reported) {
		m->own_id_reported = true;
		m->cnt.duplicates++;
		note_first_error(m, m->own_id, 0, 0);
		emit_node(m, m->own_id, CO_MGR_NODE_OWN_ID, 0);
	}
	co_fsm_goto(&m->fsm, CO_MGR_FATAL, now_us);
}

static void own_id_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	co_manager *m = arg;
	(void)node;
	(void)f;
	mgr_enter(m, now_us);
	own_id_conflict(m, now_us);
	mgr_after(m, now_us);
}

static void duplicate(co_manager *m, struct mgr_slave *s, uint32_t why)
{
	if (s->dup_reported)
		return;
	s->dup_reported = true;
	m->cnt.duplicates++;
	emit_node(m, s->id, CO_MGR_NODE_DUPLICATE, why);
}

static void unexpected(co_manager *m, struct mgr_slave *s)
{
	if (s->unexpected_reported)
		return;
	s->unexpected_reported = true;
	m->cnt.unexpected++;
	emit_node(m, s->id, CO_MGR_NODE_UNEXPECTED, 0);
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
	if (mst == CO_MGR_STOPPED) {
		/* seed 001 §2.2 STOP: no SDO services; the node is stopped too
		 * and booted when the network leaves STOPPED */
		co_fsm_goto(&s->fsm, BS_IDLE, now_us);
		s->d.booted = false;
		s->boot_deferred = true;
		nmt_send(m, s->id, CO_NMT_CS_STOP, now_us);
		return;
	}
	/* late or rebooted node: its boot slave process runs again */
	/* late: it was looked for and missing, and shows up now */
	if (!s->ever_booted && s->attempted)
		emit_node(m, s->id, CO_MGR_NODE_LATE, 0);
	if (s->lost)
		emit_node(m, s->id, CO_MGR_NODE_BACK, 0);
	s->d.booted = false;
	bs_begin(s, false, false, now_us);
	m->check_pending = true;
}

/* Error control lost (E: heartbeat, F: guarding) for a booted slave:
 * the 1F80h reaction for a mandatory one, else that node alone is reset
 * and booted again when it comes back. */
static void on_errctrl_lost(co_manager *m, struct mgr_slave *s, char letter, uint64_t now_us)
{
	uint32_t b80 = f80(m);
	uint8_t mst = (uint8_t)co_fsm_state_of(&m->fsm);

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
	note_first_error(m, s->id, letter, 0);
	emit_node(m, s->id, CO_MGR_NODE_LOST, (uint32_t)letter);
	co_fsm_goto(&s->fsm, BS_IDLE, now_us);
	if (letter == 'F')
		(void)co_guard_master_remove(m->node, s->id);
	if (is_mandatory(m, s->id) && (b80 & CO_MGR_1F80_RESET_ALL_ON_ERROR)) {
		emit_node(m, s->id, CO_MGR_NODE_ERROR_REACTION, CO_NMT_CS_RESET_NODE);
		/* "reset all nodes, including itself" (seed 001 §2.2 transition
		 * 26): our own node leaves OPERATIONAL like the others and is
		 * started again with the network; its OD is kept (a reset of
		 * it would lose what clients wrote through the mailbox) */
		(void)co_nmt_local_cmd(m->node, CO_NMT_CS_ENTER_PREOP, now_us);
		m->reset_cs = CO_NMT_CS_RESET_NODE;
		co_fsm_goto(&m->fsm, CO_MGR_RESETTING, now_us);
		return;
	}
	if (is_mandatory(m, s->id) && (b80 & CO_MGR_1F80_STOP_ALL_ON_ERROR)) {
		emit_node(m, s->id, CO_MGR_NODE_ERROR_REACTION, CO_NMT_CS_STOP);
		nmt_send(m, 0, CO_NMT_CS_STOP, now_us);
		m->net_started = false;
		if (mst != CO_MGR_STOPPED)
			co_fsm_goto(&m->fsm, CO_MGR_STOPPED, now_us);
		return;
	}
	emit_node(m, s->id, CO_MGR_NODE_ERROR_REACTION, 0);
	nmt_send(m, s->id, CO_NMT_CS_RESET_COMM, now_us);
	m->check_pending = true;
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
	/* A node that just sent its boot-up is pre-operational; it reporting
	 * OPERATIONAL or STOPPED before anybody told it so means a second
	 * device answers on that ID (or the first never rebooted). */
	if (s->bootup_us && !s->cmd_since_bootup && !guarded &&
	    (st == CO_NMT_OPERATIONAL || st == CO_NMT_STOPPED) &&
	    (mine == CO_NMT_PRE_OPERATIONAL || prev == CO_NMT_INITIALISING) &&
	    !(assignment(m, s->id) & CO_MGR_1F81_KEEP_ALIVE))
		duplicate(m, s, st);
	if (bs_state(s) == BS_KEEP_ALIVE || (guarded && bs_state(s) == BS_ERRCTRL))
		bs_input(s, &in, now_us);
	/* KEEP_OP (seed 003): it left OPERATIONAL without being told */
	if (s->keep_op && bs_state(s) == BS_BOOTED && prev == CO_NMT_OPERATIONAL &&
	    st != CO_NMT_OPERATIONAL && s->expected_state == CO_NMT_OPERATIONAL && m->net_started) {
		m->cnt.keep_op_restarts++;
		emit_node(m, s->id, CO_MGR_NODE_KEEP_OP, st);
		nmt_send(m, s->id, CO_NMT_CS_START, now_us);
	}
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
		note_first_error(m, s->id, 0, e->code);
}

void co_manager_on_event(co_manager *m, const co_event *ev)
{
	uint64_t now = ev->now_us;
	const co_ev_errctrl *ec = &ev->u.errctrl;
	struct mgr_slave *s = NULL;

	switch (ev->kind) {
	case CO_EV_BOOTUP:
	case CO_EV_HB_STATE:
	case CO_EV_HB_STARTED:
	case CO_EV_HB_LOST:
	case CO_EV_GUARD_FAILED:
	case CO_EV_GUARD_RESUMED:
		if (ec->node < 1 || ec->node > 127)
			return;
		s = &m->s[ec->node];
		break;
	case CO_EV_EMCY_RX:
		if (ev->u.emcy.node < 1 || ev->u.emcy.node > 127)
			return;
		on_emcy(m, &m->s[ev->u.emcy.node], &ev->u.emcy, now);
		return;
	case CO_EV_SDO_CLIENT_SECOND_ANSWER:
		/* two answers to one SDO request: two devices on that ID */
		if (ev->u.sdo_cli.node_id < 1 || ev->u.sdo_cli.node_id > 127 ||
		    ev->u.sdo_cli.node_id == m->own_id)
			return;
		mgr_enter(m, now);
		duplicate(m, &m->s[ev->u.sdo_cli.node_id], CO_MGR_DUP_SDO_ANSWERS);
		mgr_after(m, now);
		return;
	case CO_EV_NMT_STATE:
		/* our own state is a flag of the line state (manager operational) */
		mgr_enter(m, now);
		mgr_after(m, now);
		return;
	default:
		return;
	}
	if (!is_master(m) && co_fsm_state_of(&m->fsm) == CO_MGR_SLAVE)
		return;
	mgr_enter(m, now);
	if (ec->node == m->own_id) {
		own_id_conflict(m, now);
	} else {
		struct mgr_in in = { .kind = IN_HB, .guarded = ec->guarded };
		switch (ev->kind) {
		case CO_EV_BOOTUP:
			on_bootup(m, s, now);
			break;
		case CO_EV_HB_STATE:
			on_state(m, s, ec->state, ec->prev, ec->guarded, now);
			break;
		case CO_EV_HB_STARTED:
		case CO_EV_GUARD_RESUMED:
			if (ec->state != CO_HB_STATE_UNKNOWN)
				s->last_state = ec->state;
			if (bs_state(s) == BS_ERRCTRL) {
				bs_input(s, &in, now);
			} else if (s->lost && bs_state(s) == BS_IDLE && mgr_active(m) &&
				   is_bootable(m, s->id)) {
				emit_node(m, s->id, CO_MGR_NODE_BACK, 0);
				bs_begin(s, false, false, now);
			}
			break;
		case CO_EV_HB_LOST:
			on_errctrl_lost(m, s, 'E', now);
			break;
		case CO_EV_GUARD_FAILED:
			on_errctrl_lost(m, s, 'F', now);
			break;
		default:
			break;
		}
	}
	mgr_after(m, now);
}

/* NMT commands from the bus addressed to the manager's own node: ignored
 * and counted while it is NMT master (unless configured otherwise). */
static bool nmt_rx_filter(void *ctx, co_node *node, uint8_t cs, uint8_t target, uint64_t now_us)
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
	emit(m, CO_EV_MGR_NODE, &e);
	mgr_after(m, now_us);
	return false;
}

/* ---- timers ---------------------------------------------------------------------- */

uint64_t co_manager_next_deadline_us(const co_manager *m)
{
	uint64_t t = m->autostart_pending ? 0 : CO_NO_DEADLINE;
	if (m->timer_us < t)
		t = m->timer_us;
	if (m->scan_us < t)
		t = m->scan_us;
	for (unsigned id = 1; id <= 127; id++)
		if (m->s[id].timer_us < t)
			t = m->s[id].timer_us;
	return t;
}

/* Scan for missing assigned nodes: nodes neither booted nor booting get
 * their boot slave process again (their 1000h read is the probe). */
static void scan(co_manager *m, uint64_t now_us)
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
		bs_begin(s, false, false, now_us);
	}
}

uint64_t co_manager_tick(co_manager *m, uint64_t now_us)
{
	mgr_enter(m, now_us);
	if (m->autostart_pending) {
		m->autostart_pending = false;
		co_fsm_goto(&m->fsm, is_master(m) ? CO_MGR_RESETTING : CO_MGR_SLAVE, now_us);
	}
	if (m->timer_us <= now_us) {
		m->timer_us = CO_NO_DEADLINE;
		co_fsm_timeout(&m->fsm, now_us);
	}
	for (unsigned id = 1; id <= 127; id++) {
		struct mgr_slave *s = &m->s[id];
		if (s->timer_us <= now_us) {
			s->timer_us = CO_NO_DEADLINE;
			co_fsm_timeout(&s->fsm, now_us);
		}
	}
	if (m->cfg.scan_ms && m->scan_us <= now_us) {
		scan(m, now_us);
		m->scan_us = now_us + (uint64_t)m->cfg.scan_ms * 1000u;
	}
	mgr_after(m, now_us);
	return co_manager_next_deadline_us(m);
}

/* ---- requests -------------------------------------------------------------------- */

int co_manager_boot_network(co_manager *m, uint64_t now_us)
{
	if (!is_master(m))
		return -EPERM;
	mgr_enter(m, now_us);
	m->autostart_pending = false;
	m->own_id_reported = false;
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
	bs_begin(&m->s[node_id], false, false, now_us);
	m->check_pending = true;
	mgr_after(m, now_us);
	return 0;
}

int co_manager_start_network(co_manager *m, uint64_t now_us)
{
	if (!mgr_active(m))
		return -EPERM;
	if (!all_mandatory_booted(m))
		return -EAGAIN;
	mgr_enter(m, now_us);
	m->awaiting_mandatory = false;
	start_network_now(m, true, now_us);
	mgr_after(m, now_us);
	return 0;
}

static int cmd_to_cs(uint8_t cmd)
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

/* The network leaves STOPPED: the nodes that booted up meanwhile are
 * booted now. True if there were any. */
static bool boot_deferred_nodes(co_manager *m, uint64_t now_us)
{
	bool any = false;
	for (unsigned id = 1; id <= 127; id++) {
		struct mgr_slave *s = &m->s[id];
		if (!s->boot_deferred)
			continue;
		s->boot_deferred = false;
		any = true;
		/* it was stopped: no SDO before it is pre-operational again */
		nmt_send(m, (uint8_t)id, CO_NMT_CS_ENTER_PREOP, now_us);
		bs_begin(s, false, false, now_us);
	}
	if (any)
		m->check_pending = true;
	return any;
}

static int request_all(co_manager *m, uint8_t cs, uint64_t now_us)
{
	switch (cs) {
	case CO_NMT_CS_START:
		if (co_fsm_state_of(&m->fsm) == CO_MGR_STOPPED && boot_deferred_nodes(m, now_us) &&
		    !all_mandatory_booted(m)) {
			/* started once the rebooted mandatory nodes booted */
			m->awaiting_mandatory = true;
			co_fsm_goto(&m->fsm, CO_MGR_BOOTED, now_us);
			return 0;
		}
		if (!all_mandatory_booted(m))
			return -EAGAIN;
		m->awaiting_mandatory = false;
		start_network_now(m, true, now_us);
		return 0;
	case CO_NMT_CS_STOP:
	case CO_NMT_CS_ENTER_PREOP:
		if (cs == CO_NMT_CS_ENTER_PREOP)
			(void)boot_deferred_nodes(m, now_us);
		nmt_send(m, 0, cs, now_us);
		m->net_started = false;
		co_fsm_goto(&m->fsm, cs == CO_NMT_CS_STOP ? CO_MGR_STOPPED : CO_MGR_PREOP, now_us);
		return 0;
	default: /* resets: the network boot runs again */
		m->reset_cs = cs;
		co_fsm_goto(&m->fsm, CO_MGR_RESETTING, now_us);
		return 0;
	}
}

int co_manager_request_nmt(co_manager *m, uint8_t node_id, uint8_t cmd, uint64_t now_us)
{
	int cs = cmd_to_cs(cmd), rc = 0;

	if (cs < 0 || node_id < 1 || node_id > CO_MGR_ALL_NODES)
		return -EINVAL;
	if (!is_master(m) || co_fsm_state_of(&m->fsm) == CO_MGR_SLAVE)
		return -EPERM;
	mgr_enter(m, now_us);
	{
		co_ev_mgr e = { .node = node_id == CO_MGR_ALL_NODES ? 0 : node_id,
				.what = CO_MGR_NODE_REQUEST_NMT,
				.value = cmd };
		emit(m, CO_EV_MGR_NODE, &e);
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
		nmt_send(m, node_id, (uint8_t)cs, now_us);
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

int co_manager_configure_done(co_manager *m, uint8_t node_id, uint32_t abort, uint16_t index,
			      uint8_t sub, uint32_t entry, uint64_t now_us)
{
	struct mgr_in in = {
		.kind = IN_CONFIGURED, .abort = abort, .value = entry, .index = index, .sub = sub
	};
	if (node_id < 1 || node_id > 127)
		return -EINVAL;
	if (bs_state(&m->s[node_id]) != BS_CONFIGURE)
		return -ENOENT;
	mgr_enter(m, now_us);
	bs_input(&m->s[node_id], &in, now_us);
	mgr_after(m, now_us);
	return 0;
}

int co_manager_software_done(co_manager *m, uint8_t node_id, char status, uint32_t abort,
			     uint16_t index, uint8_t sub, uint64_t now_us)
{
	struct mgr_in in = { .kind = IN_SOFTWARE,
			     .abort = abort,
			     .index = index,
			     .sub = sub,
			     .value = (uint8_t)status };
	if (node_id < 1 || node_id > 127 || (status && !strchr("GHI", status)))
		return -EINVAL;
	if (bs_state(&m->s[node_id]) != BS_SOFTWARE)
		return -ENOENT;
	mgr_enter(m, now_us);
	bs_input(&m->s[node_id], &in, now_us);
	mgr_after(m, now_us);
	return 0;
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

uint8_t co_manager_state(const co_manager *m)
{
	return (uint8_t)co_fsm_state_of(&m->fsm);
}

uint8_t co_manager_flags(const co_manager *m)
{
	return compute_flags(m);
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
	out->flags = compute_flags(m);
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
	m->own_id_reported = false;
}

/* ---- 1F82h, 1F25h ------------------------------------------------------------------ */

static uint32_t f82_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_manager *m = ctx;
	int rc;
	if (a->origin == CO_OD_ORIGIN_RESET)
		return 0;
	if (!a->data || a->size != 1)
		return SDO_AB_TYPE_LEN;
	if (cmd_to_cs(a->data[0]) < 0)
		return SDO_AB_VALUE;
	rc = co_manager_request_nmt(m, e->sub, a->data[0], m->node->now_us);
	return sdo_abort_of_errno(rc);
}

static uint32_t f82_read(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_manager *m = ctx;
	(void)a;
	co_od_entry_set_raw(e, e->sub <= 127 ? co_manager_node_nmt_state(m, e->sub) : 0);
	return 0;
}

static const co_od_hooks f82_hooks = { .check_write = f82_check, .read = f82_read };

static uint32_t f25_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_manager *m = ctx;
	uint32_t sig;
	uint64_t now = m->node->now_us;
	if (a->origin == CO_OD_ORIGIN_RESET)
		return 0;
	if (!a->data || a->size != 4)
		return SDO_AB_TYPE_LEN;
	sig = (uint32_t)a->data[0] | (uint32_t)a->data[1] << 8 | (uint32_t)a->data[2] << 16 |
	      (uint32_t)a->data[3] << 24;
	if (sig != CO_MGR_CONF_SIGNATURE)
		return SDO_AB_STORE;
	if (!mgr_active(m))
		return SDO_AB_DEV_STATE;
	if (e->sub == CO_MGR_ALL_NODES) {
		mgr_enter(m, now);
		for (unsigned id = 1; id <= 127; id++)
			if (is_slave(m, (uint8_t)id) && !bs_running(&m->s[id])) {
				m->s[id].d.booted = false;
				bs_begin(&m->s[id], false, false, now);
			}
		m->check_pending = true;
		mgr_after(m, now);
		return 0;
	}
	if (bs_running(&m->s[e->sub]))
		return SDO_AB_DEV_STATE;
	return co_manager_boot_node(m, e->sub, now) < 0 ? SDO_AB_DEV_STATE : 0;
}

static const co_od_hooks f25_hooks = { .check_write = f25_check };

/* 1F80h, 1F81h, 1F84h..1F89h while the network boots (seed 001 §2.7: locked
 * during the network initialisation): the boot reads them step by step, a
 * change in the middle would boot a node against half old, half new
 * values. 1F89h stays writable while the line waits for mandatory slaves
 * (seed 001 §2.1 step 5: 0 = wait for ever, else a new limit). The
 * flying master (1F80h bit 5) is not supported. Writes are refused with
 * 08000022h (device state) or 06090030h (value range). */
static uint32_t lock_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_manager *m = ctx;
	uint8_t st = (uint8_t)co_fsm_state_of(&m->fsm);
	if (a->origin == CO_OD_ORIGIN_RESET)
		return 0;
	if (e->index == 0x1F80 && a->data && a->size >= 1 &&
	    (a->data[0] & CO_MGR_1F80_FLYING_MASTER))
		return SDO_AB_VALUE;
	if (st == CO_MGR_RESETTING || st == CO_MGR_BOOTING)
		return SDO_AB_DEV_STATE;
	if (st == CO_MGR_WAIT_MANDATORY && e->index != 0x1F89)
		return SDO_AB_DEV_STATE;
	return 0;
}

static const co_od_hooks lock_hooks = { .check_write = lock_check };

/* 1F89h written while the line waits for mandatory slaves: the new boot
 * time counts from the start of the boot (0 = wait for ever); one that
 * has passed ends the wait at the next tick. */
static void boot_time_written(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_manager *m = ctx;
	uint32_t bt = od_u32(m, 0x1F89, 0);
	(void)e;
	(void)a;
	if (co_fsm_state_of(&m->fsm) != CO_MGR_WAIT_MANDATORY)
		return;
	m->timer_us = bt ? m->boot_started_us + (uint64_t)bt * 1000u : CO_NO_DEADLINE;
}

static const co_od_hooks boot_time_hooks = { .check_write = lock_check,
					     .after_write = boot_time_written };

/* The objects lock_check guards (sub-index ranges). */
static const struct locked_object {
	uint16_t index;
	uint8_t first, last;
} locked_objects[] = {
	{ 0x1F80, 0, 0 },   { 0x1F81, 1, 127 }, { 0x1F84, 1, 127 }, { 0x1F85, 1, 127 },
	{ 0x1F86, 1, 127 }, { 0x1F87, 1, 127 }, { 0x1F88, 1, 127 }, { 0x1F89, 0, 0 },
};

static void set_lock_hooks(co_manager *m, bool on)
{
	for (size_t i = 0; i < sizeof(locked_objects) / sizeof(locked_objects[0]); i++)
		for (unsigned sub = locked_objects[i].first; sub <= locked_objects[i].last; sub++)
			(void)co_od_set_hooks(m->od, locked_objects[i].index, (uint8_t)sub,
					      !on                                 ? NULL
					      : locked_objects[i].index == 0x1F89 ? &boot_time_hooks
										  : &lock_hooks,
					      on ? m : NULL);
}

int co_od_add_manager_defaults(co_od *od, uint32_t f80_def)
{
	int rc;
	if ((rc = co_od_ensure_num(od, 0x1F80, 0, CO_T_UNSIGNED32, CO_ACC_RW | CO_ACC_PERSIST,
				   f80_def, 0)) < 0)
		return rc;
	if ((rc = co_od_ensure_num(od, 0x1F89, 0, CO_T_UNSIGNED32, CO_ACC_RW | CO_ACC_PERSIST, 0,
				   0)) < 0)
		return rc;
	static const uint16_t arrays[] = { 0x1F81, 0x1F84, 0x1F85, 0x1F86, 0x1F87, 0x1F88 };
	for (size_t i = 0; i < sizeof(arrays) / sizeof(arrays[0]); i++)
		if (!co_od_has_index(od, arrays[i]) &&
		    (rc = co_od_add_array(od, arrays[i], CO_T_UNSIGNED32, 127,
					  CO_ACC_RW | CO_ACC_PERSIST, 0)) < 0)
			return rc;
	if (!co_od_has_index(od, 0x1F82) &&
	    (rc = co_od_add_array(od, 0x1F82, CO_T_UNSIGNED8, 128, CO_ACC_RW, 0)) < 0)
		return rc;
	if (!co_od_has_index(od, 0x1F25) &&
	    (rc = co_od_add_array(od, 0x1F25, CO_T_UNSIGNED32, 128, CO_ACC_WO, 0)) < 0)
		return rc;
	if ((rc = co_od_add_comm_defaults_nmt(od, 1)) < 0)
		return rc;
	return co_od_add_comm_defaults_hb(od, 127, 0);
}

/* ---- life cycle ------------------------------------------------------------------ */

int co_manager_create(co_manager **out, co_node *node, const co_manager_config *cfg)
{
	co_manager *m;
	uint8_t n_cli = sdo_client_channel_count(node);

	*out = NULL;
	if (!cfg || !n_cli)
		return -EINVAL;
	m = calloc(1, sizeof(*m));
	if (!m)
		return -ENOMEM;
	m->node = node;
	m->od = co_node_od(node);
	m->cfg = *cfg;
	m->own_id = co_node_id(node);
	m->n_slots = m->cfg.max_parallel && m->cfg.max_parallel < n_cli ? m->cfg.max_parallel
									: n_cli;
	if (!m->cfg.sdo_timeout_ms)
		m->cfg.sdo_timeout_ms = 500;
	if (!m->cfg.reset_wait_ms)
		m->cfg.reset_wait_ms = 1000;
	if (!m->cfg.retry_ms)
		m->cfg.retry_ms = 1000;
	m->timer_us = CO_NO_DEADLINE;
	m->scan_us = m->cfg.scan_ms ? 0 : CO_NO_DEADLINE;
	m->autostart_pending = !m->cfg.no_autostart;
	co_fsm_init(&m->fsm, &mgr_def, m, CO_MGR_SLAVE);
	for (unsigned id = 0; id < 128; id++) {
		struct mgr_slave *s = &m->s[id];
		s->m = m;
		s->id = (uint8_t)id;
		s->timer_us = CO_NO_DEADLINE;
		s->last_state = STATE_UNKNOWN;
		s->expected_state = STATE_UNKNOWN;
		s->target_state = CO_NMT_OPERATIONAL;
		co_fsm_init(&s->fsm, &bs_def, s, BS_IDLE);
	}
	for (unsigned i = 0; i < 3; i++)
		m->rx[i] = -1;
	if (m->own_id >= 1 && m->own_id <= 127) {
		/* frames a device on our own ID would send: heartbeat/boot-up,
		 * EMCY, SDO server answers (we never receive our own) */
		static const uint32_t base[3] = { 0x700, 0x080, 0x580 };
		for (unsigned i = 0; i < 3; i++)
			m->rx[i] = co_rx_register(node, base[i] + m->own_id, 0, own_id_rx, m);
	}
	for (unsigned sub = 1; sub <= 128; sub++) {
		(void)co_od_set_hooks(m->od, 0x1F82, (uint8_t)sub, &f82_hooks, m);
		(void)co_od_set_hooks(m->od, 0x1F25, (uint8_t)sub, &f25_hooks, m);
	}
	set_lock_hooks(m, true);
	co_nmt_set_rx_filter(node, nmt_rx_filter, m);
	*out = m;
	return 0;
}

void co_manager_destroy(co_manager *m)
{
	if (!m)
		return;
	/* requests still out would confirm into freed memory */
	m->destroying = true;
	for (unsigned id = 1; id <= 127; id++)
		if (m->s[id].sdo_pending)
			(void)sdo_client_cancel_tag(m->node, m->s[id].tag, SDO_AB_GENERAL,
						    m->node->now_us);
	co_nmt_set_rx_filter(m->node, NULL, NULL);
	for (unsigned sub = 1; sub <= 128; sub++) {
		(void)co_od_set_hooks(m->od, 0x1F82, (uint8_t)sub, NULL, NULL);
		(void)co_od_set_hooks(m->od, 0x1F25, (uint8_t)sub, NULL, NULL);
	}
	set_lock_hooks(m, false);
	for (unsigned i = 0; i < 3; i++)
		if (m->rx[i] >= 0)
			(void)co_rx_unregister(m->node, m->rx[i]);
	free(m);
}
