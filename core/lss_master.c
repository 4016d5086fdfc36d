/* SPDX-License-Identifier: MIT */
/*
 * LSS master (CiA 305). One request runs at a time, in a core/fsm.h
 * machine (the table mst_states below): the start state sends the
 * service's first frames (one start function per service) and moves to
 * the state that waits for the answer or the window. Every ending goes
 * through end(), which returns to idle; then report() calls the request's
 * con and emits the one CO_EV_LSS_MASTER_DONE, and kick() starts the next
 * queued request. A request that ends while it is being submitted
 * (switch global: done once its frame is out; a refused send) ends from
 * the next tick instead (state done-later), so that no confirmation ever
 * runs inside lss_master_submit().
 *
 * Why some choices:
 * - LSS answers carry no node address, so the master cannot tell two
 *   services' answers apart: one service at a time, a bounded FIFO for the
 *   rest (the mailbox may hand us several requests at once).
 * - Identify and Fastscan steps always listen for their whole window
 *   instead of moving on at the first answer. Several slaves may answer
 *   the same probe (on a real bus identical frames from several slaves
 *   merge into one, in a simulation they arrive one by one); moving on at
 *   the first would take a late duplicate as the answer to the next probe.
 *   Confirmed services finish at the first answer: only one slave should
 *   be in configuration state.
 * - Fastscan probes bits 31..1 one by one and settles bit 0 with the
 *   confirmation itself (bit 0 = 0 first; if nobody answers, bit 0 = 1). So
 *   a frame with BitChecked 0 always carries the real LSSNext: slave
 *   implementations differ in when a complete match moves them to
 *   configuration state (LSSNext < LSSSub, or "serial matched"), and a
 *   bit 0 probe with LSSNext = LSSSub = 3 would switch the second kind
 *   early and lose it. Cost: 32 or 33 steps per field.
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/co_internal.h"
#include "core/fsm.h"
#include "core/lss_master.h"

#define DEFAULT_TIMEOUT_MS 1000u /* CiA 305 leaves it open; 1 s is common */
#define DEFAULT_STEP_MS 100u
#define DEFAULT_QUEUE_LEN 8u

struct lss_master {
	co_node *node;
	int rx;
	uint32_t timeout_ms;
	uint32_t step_ms;

	lss_master_req *queue; /* ring of q_len, allocated at init */
	uint8_t q_len;
	uint8_t q_head;
	uint8_t q_count;
	bool cancelling;       /* lss_master_cancel_all() running: start nothing */
	bool submitting;       /* inside lss_master_submit(): end later */
	lss_result done_later; /* LSS_MASTER_DONE_LATER: the result */

	co_fsm fsm; /* state: lss_master_state */
	lss_master_req cur;
	uint64_t deadline_us;    /* of the running state; CO_NO_DEADLINE */
	uint64_t quiet_until_us; /* after activate bit timing */
	uint8_t expect_cs;       /* answer the running state listens for */
	co_ev_lss_master res;    /* result being built */
	bool ended;              /* cur ended with end_result: report it
	                          * once the machine has settled in idle */
	lss_result end_result;

	uint8_t fs_sub;     /* Fastscan: field being scanned */
	uint8_t fs_bit;     /* Fastscan: bit being probed */
	bool fs_bit0_retry; /* Fastscan: confirming with bit 0 = 1 */
};

/* ---- names ------------------------------------------------------------------ */

const char *lss_master_service_to_string(lss_master_service s)
{
	switch (s) {
	case LSS_SVC_NONE:
		return "none";
	case LSS_SVC_SWITCH_GLOBAL:
		return "switch-global";
	case LSS_SVC_SWITCH_SELECTIVE:
		return "switch-selective";
	case LSS_SVC_CONFIG_NODE_ID:
		return "config-node-id";
	case LSS_SVC_CONFIG_BIT_TIMING:
		return "config-bit-timing";
	case LSS_SVC_ACTIVATE_BIT_TIMING:
		return "activate-bit-timing";
	case LSS_SVC_STORE:
		return "store";
	case LSS_SVC_INQUIRE_VENDOR:
		return "inquire-vendor";
	case LSS_SVC_INQUIRE_PRODUCT:
		return "inquire-product";
	case LSS_SVC_INQUIRE_REVISION:
		return "inquire-revision";
	case LSS_SVC_INQUIRE_SERIAL:
		return "inquire-serial";
	case LSS_SVC_INQUIRE_NODE_ID:
		return "inquire-node-id";
	case LSS_SVC_IDENTIFY_REMOTE:
		return "identify-remote";
	case LSS_SVC_IDENTIFY_NON_CONFIGURED:
		return "identify-non-configured";
	case LSS_SVC_FASTSCAN:
		return "fastscan";
	case LSS_SVC_COUNT:
		break;
	}
	return "?";
}

const char *lss_result_to_string(lss_result r)
{
	switch (r) {
	case LSS_RESULT_OK:
		return "ok";
	case LSS_RESULT_SLAVE_ERROR:
		return "slave error";
	case LSS_RESULT_TIMEOUT:
		return "timeout";
	case LSS_RESULT_NOT_FOUND:
		return "no slave answered";
	case LSS_RESULT_SCAN_LOST:
		return "fastscan lost the slave";
	case LSS_RESULT_CANCELLED:
		return "cancelled";
	case LSS_RESULT_TX_FAILED:
		return "send failed";
	}
	return "?";
}

/* ---- plumbing ------------------------------------------------------------------ */

static struct lss_master *master_of(const co_node *node)
{
	return node->lss ? node->lss->master : NULL;
}

static bool busy(const struct lss_master *m)
{
	return co_fsm_state_of(&m->fsm) != LSS_MASTER_IDLE;
}

static uint64_t next_deadline(const struct lss_master *m)
{
	if (busy(m))
		return m->deadline_us;
	if (m->q_count)
		return m->quiet_until_us; /* in the past: kick at the next tick */
	return CO_NO_DEADLINE;
}

/* Entering a waiting state: its deadline, a fresh answer count. */
static int arm(struct lss_master *m, uint32_t ms, uint64_t now_us)
{
	m->deadline_us = now_us + (uint64_t)ms * 1000u;
	m->res.answers = 0;
	co_node_deadline_lower(m->node, m->deadline_us);
	return CO_FSM_STAY;
}

static uint32_t cur_timeout_ms(const struct lss_master *m)
{
	if (m->cur.timeout_ms)
		return m->cur.timeout_ms;
	return m->cur.service == LSS_SVC_FASTSCAN ? m->step_ms : m->timeout_ms;
}

/* The running request ended with r: back to idle; the confirmation and
 * the event follow once the machine has settled (report()), so that a
 * confirmation submitting the next request finds the master idle. Inside
 * lss_master_submit() nothing may be reported: wait for the next tick. */
static int end(struct lss_master *m, lss_result r)
{
	if (m->submitting) {
		m->done_later = r;
		return LSS_MASTER_DONE_LATER;
	}
	m->ended = true;
	m->end_result = r;
	return LSS_MASTER_IDLE;
}

/* Confirmation, then the one CO_EV_LSS_MASTER_DONE, of the request that
 * ended (if one did). */
static void report(struct lss_master *m, uint64_t now_us)
{
	co_event ev = { .kind = CO_EV_LSS_MASTER_DONE };
	lss_master_con_fn con = m->cur.con;
	void *con_arg = m->cur.con_arg;

	if (!m->ended)
		return;
	m->ended = false;
	m->res.service = (uint8_t)m->cur.service;
	m->res.result = (uint8_t)m->end_result;
	m->res.tag = m->cur.tag;
	ev.u.lss_master = m->res;
	ev.now_us = now_us;
	if (con)
		con(con_arg, &ev.u.lss_master);
	co_node_emit(m->node, &ev);
}

/* Send one LSS request: cs and up to 7 payload bytes, padded to 8. */
static int send_cmd(struct lss_master *m, uint8_t cs, const uint8_t *p, unsigned n)
{
	co_frame f;

	co_frame_init(&f, LSS_COBID_MASTER, 8);
	f.data[0] = cs;
	for (unsigned i = 0; i < n && i < 7; i++)
		f.data[1 + i] = p[i];
	return co_node_send(m->node, &f);
}

static int send_u32(struct lss_master *m, uint8_t cs, uint32_t v)
{
	uint8_t p[4];

	co_put_le32(p, v);
	return send_cmd(m, cs, p, 4);
}

/* ---- idle, done-later ------------------------------------------------------------ */

static int idle_on_enter(void *obj, uint64_t now_us)
{
	struct lss_master *m = obj;

	(void)now_us;
	m->deadline_us = CO_NO_DEADLINE;
	return CO_FSM_STAY;
}

/* Ended inside lss_master_submit(): report from the next tick. */
static int done_later_on_enter(void *obj, uint64_t now_us)
{
	struct lss_master *m = obj;

	m->deadline_us = now_us;
	co_node_deadline_lower(m->node, now_us);
	return CO_FSM_STAY;
}

static int done_later_on_timeout(void *obj, uint64_t now_us)
{
	struct lss_master *m = obj;

	(void)now_us;
	return end(m, m->done_later);
}

/* ---- confirmed services ------------------------------------------------------------ */

static int confirm_on_enter(void *obj, uint64_t now_us)
{
	struct lss_master *m = obj;

	return arm(m, cur_timeout_ms(m), now_us);
}

static int confirm_error_answer(struct lss_master *m, const co_frame *f)
{
	if (f->len < 2)
		return CO_FSM_STAY; /* no error code: not an answer */
	m->res.error_code = f->data[1];
	m->res.error_spec = f->len >= 3 ? f->data[2] : 0;
	return end(m, f->data[1] == LSS_EC_OK ? LSS_RESULT_OK : LSS_RESULT_SLAVE_ERROR);
}

static int confirm_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct lss_master *m = obj;

	(void)now_us;
	switch ((lss_cs)f->data[0]) {
	case LSS_CS_SWITCH_SEL_RESPONSE:
		return end(m, LSS_RESULT_OK);
	case LSS_CS_CONFIG_NODE_ID:
	case LSS_CS_CONFIG_BIT_TIMING:
	case LSS_CS_STORE:
		return confirm_error_answer(m, f);
	case LSS_CS_INQUIRE_NODE_ID:
		if (f->len < 2)
			return CO_FSM_STAY;
		m->res.node_id = f->data[1];
		return end(m, LSS_RESULT_OK);
	default: /* inquire vendor..serial */
		if (f->len < 5)
			return CO_FSM_STAY;
		m->res.value = co_get_le32(&f->data[1]);
		return end(m, LSS_RESULT_OK);
	}
}

static int confirm_on_timeout(void *obj, uint64_t now_us)
{
	(void)now_us;
	return end(obj, LSS_RESULT_TIMEOUT);
}

/* ---- identify windows (also every Fastscan step): count the answers --------------- */

static int window_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct lss_master *m = obj;

	(void)f;
	(void)now_us;
	if (m->res.answers < UINT16_MAX)
		m->res.answers++;
	return CO_FSM_STAY;
}

static int window_on_timeout(void *obj, uint64_t now_us)
{
	struct lss_master *m = obj;

	(void)now_us;
	return end(m, m->res.answers ? LSS_RESULT_OK : LSS_RESULT_NOT_FOUND);
}

/* ---- activate bit timing ------------------------------------------------------------ */

static int activate_on_enter(void *obj, uint64_t now_us)
{
	struct lss_master *m = obj;

	return arm(m, m->cur.delay_ms, now_us);
}

static int activate_on_timeout(void *obj, uint64_t now_us)
{
	struct lss_master *m = obj;

	/* First delay over: every node switches now. The second delay keeps
	 * the bus quiet while they come back (CiA 305). */
	m->quiet_until_us = now_us + (uint64_t)m->cur.delay_ms * 1000u;
	return end(m, LSS_RESULT_OK);
}

/* ---- Fastscan ------------------------------------------------------------------------ */

/* Send one Fastscan frame for the current field; the caller then enters
 * (or re-enters) the step state st, which arms the step's window. */
static int fs_send(struct lss_master *m, int st, uint8_t bit, uint8_t next)
{
	uint8_t p[7];

	co_put_le32(p, m->res.identity[m->fs_sub]);
	p[4] = bit;
	p[5] = m->fs_sub;
	p[6] = next;
	if (send_cmd(m, LSS_CS_FASTSCAN, p, 7) < 0)
		return end(m, LSS_RESULT_TX_FAILED);
	return st;
}

static int fs_probe(struct lss_master *m)
{
	return fs_send(m, LSS_MASTER_FS_BIT, m->fs_bit, m->fs_sub);
}

/* BitChecked 0 with the next field: the slave matching the whole value
 * moves on (or, after the last field, into configuration state). */
static int fs_confirm(struct lss_master *m)
{
	return fs_send(m, LSS_MASTER_FS_CONFIRM, 0, (uint8_t)((m->fs_sub + 1) % LSS_ID_COUNT));
}

static int fs_begin_field(struct lss_master *m)
{
	if (m->cur.known_mask & (1u << m->fs_sub))
		return fs_confirm(m); /* value given: only confirm it */
	m->res.identity[m->fs_sub] = 0;
	m->fs_bit = 31;
	m->fs_bit0_retry = false;
	return fs_probe(m);
}

static int fs_step_on_enter(void *obj, uint64_t now_us)
{
	struct lss_master *m = obj;

	return arm(m, cur_timeout_ms(m), now_us);
}

static int fs_reset_on_timeout(void *obj, uint64_t now_us)
{
	struct lss_master *m = obj;

	(void)now_us;
	if (!m->res.answers)
		return end(m, LSS_RESULT_NOT_FOUND);
	m->fs_sub = 0;
	return fs_begin_field(m);
}

static int fs_bit_on_timeout(void *obj, uint64_t now_us)
{
	struct lss_master *m = obj;

	(void)now_us;
	/* An answer means some slave has 0 at this bit (the probe sends 0
	 * there); silence means every remaining candidate has 1. Bit 0 is
	 * left to the confirmation (see the top of the file). */
	if (!m->res.answers)
		m->res.identity[m->fs_sub] |= 1u << m->fs_bit;
	if (m->fs_bit == 1)
		return fs_confirm(m); /* bit 0 = 0 first */
	m->fs_bit--;
	return fs_probe(m);
}

static int fs_confirm_on_timeout(void *obj, uint64_t now_us)
{
	struct lss_master *m = obj;
	bool known = m->cur.known_mask & (1u << m->fs_sub);

	(void)now_us;
	if (!m->res.answers && !known && !m->fs_bit0_retry) {
		m->fs_bit0_retry = true; /* nobody has bit 0 = 0: try 1 */
		m->res.identity[m->fs_sub] |= 1u;
		return fs_confirm(m);
	}
	if (!m->res.answers)
		/* A given value nobody has is "not found"; a scanned value
		 * nobody confirms means the slave went away mid-scan. */
		return end(m, known ? LSS_RESULT_NOT_FOUND : LSS_RESULT_SCAN_LOST);
	m->fs_bit0_retry = false;
	if (++m->fs_sub == LSS_ID_COUNT)
		/* The slave saw LSSNext < LSSSub: it is in configuration
		 * state now. */
		return end(m, LSS_RESULT_OK);
	return fs_begin_field(m);
}

/* ---- service start functions: send, then the state that waits -------------------- */

/* Frames sent (rc) or not; then wait in state st for the answer expect. */
static int wait_for(struct lss_master *m, int rc, int st, uint8_t expect)
{
	if (rc < 0)
		return end(m, LSS_RESULT_TX_FAILED);
	m->expect_cs = expect;
	return st;
}

static int start_switch_global(struct lss_master *m)
{
	uint8_t mode = m->cur.mode;

	return end(m, send_cmd(m, LSS_CS_SWITCH_GLOBAL, &mode, 1) < 0 ? LSS_RESULT_TX_FAILED
								      : LSS_RESULT_OK);
}

static int start_switch_selective(struct lss_master *m)
{
	int rc = 0;

	for (unsigned i = 0; i < LSS_ID_COUNT && rc == 0; i++)
		rc = send_u32(m, (uint8_t)(LSS_CS_SWITCH_SEL_VENDOR + i), m->cur.addr.id[i]);
	return wait_for(m, rc, LSS_MASTER_CONFIRM, LSS_CS_SWITCH_SEL_RESPONSE);
}

static int start_config_node_id(struct lss_master *m)
{
	m->res.node_id = m->cur.node_id;
	return wait_for(m, send_cmd(m, LSS_CS_CONFIG_NODE_ID, &m->cur.node_id, 1),
			LSS_MASTER_CONFIRM, LSS_CS_CONFIG_NODE_ID);
}

static int start_config_bit_timing(struct lss_master *m)
{
	uint8_t p[2] = { m->cur.table, m->cur.index };

	return wait_for(m, send_cmd(m, LSS_CS_CONFIG_BIT_TIMING, p, 2), LSS_MASTER_CONFIRM,
			LSS_CS_CONFIG_BIT_TIMING);
}

static int start_activate_bit_timing(struct lss_master *m)
{
	uint8_t p[2];

	co_put_le16(p, m->cur.delay_ms);
	return wait_for(m, send_cmd(m, LSS_CS_ACTIVATE_BIT_TIMING, p, 2), LSS_MASTER_ACTIVATE, 0);
}

static int start_store(struct lss_master *m)
{
	return wait_for(m, send_cmd(m, LSS_CS_STORE, NULL, 0), LSS_MASTER_CONFIRM, LSS_CS_STORE);
}

static int start_inquire(struct lss_master *m)
{
	uint8_t cs = (uint8_t)(LSS_CS_INQUIRE_VENDOR + (m->cur.service - LSS_SVC_INQUIRE_VENDOR));

	return wait_for(m, send_cmd(m, cs, NULL, 0), LSS_MASTER_CONFIRM, cs);
}

static int start_identify_remote(struct lss_master *m)
{
	const uint32_t v[6] = {
		m->cur.addr.id[LSS_ID_VENDOR],   m->cur.addr.id[LSS_ID_PRODUCT],
		m->cur.addr.id[LSS_ID_REVISION], m->cur.addr_high.id[LSS_ID_REVISION],
		m->cur.addr.id[LSS_ID_SERIAL],   m->cur.addr_high.id[LSS_ID_SERIAL],
	};
	int rc = 0;

	for (unsigned i = 0; i < 6 && rc == 0; i++)
		rc = send_u32(m, (uint8_t)(LSS_CS_IDENT_VENDOR + i), v[i]);
	return wait_for(m, rc, LSS_MASTER_WINDOW, LSS_CS_IDENT_SLAVE);
}

static int start_identify_non_configured(struct lss_master *m)
{
	return wait_for(m, send_cmd(m, LSS_CS_IDENT_NON_CONFIGURED, NULL, 0), LSS_MASTER_WINDOW,
			LSS_CS_IDENT_NON_CONFIGURED_SLAVE);
}

static int start_fastscan(struct lss_master *m)
{
	for (unsigned i = 0; i < LSS_ID_COUNT; i++)
		m->res.identity[i] = (m->cur.known_mask & (1u << i)) ? m->cur.addr.id[i] : 0;
	m->fs_sub = 0;
	m->expect_cs = LSS_CS_IDENT_SLAVE;
	/* IDNumber 0 and sub 0 as placeholders: with BitChecked 80h the
	 * slaves only reset their position and answer. */
	return fs_send(m, LSS_MASTER_FS_RESET, LSS_FASTSCAN_CONFIRM, 0);
}

typedef int (*mst_start_fn)(struct lss_master *m);

static const mst_start_fn mst_start[LSS_SVC_COUNT] = {
	[LSS_SVC_SWITCH_GLOBAL] = start_switch_global,
	[LSS_SVC_SWITCH_SELECTIVE] = start_switch_selective,
	[LSS_SVC_CONFIG_NODE_ID] = start_config_node_id,
	[LSS_SVC_CONFIG_BIT_TIMING] = start_config_bit_timing,
	[LSS_SVC_ACTIVATE_BIT_TIMING] = start_activate_bit_timing,
	[LSS_SVC_STORE] = start_store,
	[LSS_SVC_INQUIRE_VENDOR] = start_inquire,
	[LSS_SVC_INQUIRE_PRODUCT] = start_inquire,
	[LSS_SVC_INQUIRE_REVISION] = start_inquire,
	[LSS_SVC_INQUIRE_SERIAL] = start_inquire,
	[LSS_SVC_INQUIRE_NODE_ID] = start_inquire,
	[LSS_SVC_IDENTIFY_REMOTE] = start_identify_remote,
	[LSS_SVC_IDENTIFY_NON_CONFIGURED] = start_identify_non_configured,
	[LSS_SVC_FASTSCAN] = start_fastscan,
};

/* The request in cur starts: send its first frames, go where it waits. */
static int start_on_enter(void *obj, uint64_t now_us)
{
	struct lss_master *m = obj;

	(void)now_us;
	return mst_start[m->cur.service](m);
}

/* ---- the machine ---------------------------------------------------------------------- */

static const co_fsm_state mst_states[LSS_MASTER_STATE_COUNT] = {
	[LSS_MASTER_IDLE] = { .name = "idle", .on_enter = idle_on_enter },
	[LSS_MASTER_START] = { .name = "start", .on_enter = start_on_enter },
	[LSS_MASTER_CONFIRM] = { .name = "confirm",
				 .on_enter = confirm_on_enter,
				 .on_frame = confirm_on_frame,
				 .on_timeout = confirm_on_timeout },
	[LSS_MASTER_WINDOW] = { .name = "window",
				.on_enter = confirm_on_enter,
				.on_frame = window_on_frame,
				.on_timeout = window_on_timeout },
	[LSS_MASTER_ACTIVATE] = { .name = "activate",
				  .on_enter = activate_on_enter,
				  .on_timeout = activate_on_timeout },
	[LSS_MASTER_FS_RESET] = { .name = "fs-reset",
				  .on_enter = fs_step_on_enter,
				  .on_frame = window_on_frame,
				  .on_timeout = fs_reset_on_timeout },
	[LSS_MASTER_FS_BIT] = { .name = "fs-bit",
				.on_enter = fs_step_on_enter,
				.on_frame = window_on_frame,
				.on_timeout = fs_bit_on_timeout },
	[LSS_MASTER_FS_CONFIRM] = { .name = "fs-confirm",
				    .on_enter = fs_step_on_enter,
				    .on_frame = window_on_frame,
				    .on_timeout = fs_confirm_on_timeout },
	[LSS_MASTER_DONE_LATER] = { .name = "done-later",
				    .on_enter = done_later_on_enter,
				    .on_timeout = done_later_on_timeout },
};

static const co_fsm_def mst_def = {
	.name = "lss_master",
	.states = mst_states,
	.n_states = LSS_MASTER_STATE_COUNT,
};

const char *lss_master_state_to_string(lss_master_state s)
{
	return co_fsm_state_name(&mst_def, (int)s);
}

lss_master_state lss_master_state_of(const co_node *node)
{
	const struct lss_master *m = master_of(node);

	return m ? (lss_master_state)co_fsm_state_of(&m->fsm) : LSS_MASTER_IDLE;
}

/* Start queued requests while the master is idle and the bus not held
 * quiet. A start may end at once (switch global), and a confirmation may
 * submit more, hence the loop. */
static void kick(struct lss_master *m, uint64_t now_us)
{
	while (!busy(m) && !m->cancelling && m->q_count && now_us >= m->quiet_until_us) {
		m->cur = m->queue[m->q_head];
		m->q_head = (uint8_t)((m->q_head + 1) % m->q_len);
		m->q_count--;
		memset(&m->res, 0, sizeof(m->res));
		co_fsm_goto(&m->fsm, LSS_MASTER_START, now_us);
		report(m, now_us);
	}
	if (!busy(m) && m->q_count)
		co_node_deadline_lower(m->node, m->quiet_until_us);
}

/* After every input: report what ended, start what waits. */
static void settle(struct lss_master *m, uint64_t now_us)
{
	report(m, now_us);
	kick(m, now_us);
}

/* ---- receive and tick ---------------------------------------------------------------- */

static void lss_master_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	struct lss_master *m = arg;

	(void)node;
	if (!busy(m) || f->len < 1 || (f->flags & CO_FRAME_RTR) || f->data[0] != m->expect_cs)
		return; /* idle, or not what the running service waits for */
	co_fsm_frame(&m->fsm, f, now_us);
	settle(m, now_us);
}

uint64_t lss_master_tick(struct lss_master *m, uint64_t now_us)
{
	if (busy(m) && now_us >= m->deadline_us)
		co_fsm_timeout(&m->fsm, now_us);
	settle(m, now_us);
	return next_deadline(m);
}

/* ---- API ---------------------------------------------------------------------------- */

static bool req_valid(const lss_master_req *r)
{
	if (r->service <= LSS_SVC_NONE || r->service >= LSS_SVC_COUNT)
		return false;
	if (r->service == LSS_SVC_SWITCH_GLOBAL && r->mode != LSS_STATE_WAITING &&
	    r->mode != LSS_STATE_CONFIGURATION)
		return false;
	if (r->service == LSS_SVC_FASTSCAN && (r->known_mask & ~0xFu))
		return false;
	return true;
}

int lss_master_submit(co_node *node, const lss_master_req *req, uint64_t now_us)
{
	struct lss_master *m = master_of(node);

	if (!m)
		return -ENODEV;
	if (!req || !req_valid(req))
		return -EINVAL;
	if (m->q_count >= m->q_len)
		return -ENOSPC;
	m->queue[(m->q_head + m->q_count) % m->q_len] = *req;
	m->q_count++;
	/* Events emitted from here carry this time (see co_node_emit). */
	node->now_us = now_us;
	m->submitting = true;
	kick(m, now_us);
	m->submitting = false;
	return 0;
}

void lss_master_cancel_all(co_node *node, uint64_t now_us)
{
	struct lss_master *m = master_of(node);
	unsigned n;

	if (!m)
		return;
	node->now_us = now_us;
	m->cancelling = true;
	n = m->q_count; /* requests submitted by the callbacks stay */
	if (busy(m)) {
		m->ended = true;
		m->end_result = LSS_RESULT_CANCELLED;
		co_fsm_goto(&m->fsm, LSS_MASTER_IDLE, now_us);
		report(m, now_us);
	}
	while (n--) {
		m->cur = m->queue[m->q_head];
		m->q_head = (uint8_t)((m->q_head + 1) % m->q_len);
		m->q_count--;
		memset(&m->res, 0, sizeof(m->res));
		m->ended = true;
		m->end_result = LSS_RESULT_CANCELLED;
		report(m, now_us);
	}
	m->cancelling = false;
	kick(m, now_us);
}

unsigned lss_master_pending(const co_node *node)
{
	const struct lss_master *m = master_of(node);

	return m ? m->q_count + (busy(m) ? 1u : 0u) : 0;
}

int lss_master_switch_global_req(co_node *node, lss_state mode, uint64_t tag, uint64_t now_us)
{
	lss_master_req r = { .service = LSS_SVC_SWITCH_GLOBAL, .tag = tag, .mode = (uint8_t)mode };
	return lss_master_submit(node, &r, now_us);
}

int lss_master_switch_selective_req(co_node *node, const lss_address *addr, uint64_t tag,
				    uint64_t now_us)
{
	lss_master_req r = { .service = LSS_SVC_SWITCH_SELECTIVE, .tag = tag };

	if (!addr)
		return -EINVAL;
	r.addr = *addr;
	return lss_master_submit(node, &r, now_us);
}

int lss_master_config_node_id_req(co_node *node, uint8_t node_id, uint64_t tag, uint64_t now_us)
{
	lss_master_req r = { .service = LSS_SVC_CONFIG_NODE_ID, .tag = tag, .node_id = node_id };
	return lss_master_submit(node, &r, now_us);
}

int lss_master_config_bit_timing_req(co_node *node, uint8_t table, uint8_t index, uint64_t tag,
				     uint64_t now_us)
{
	lss_master_req r = {
		.service = LSS_SVC_CONFIG_BIT_TIMING, .tag = tag, .table = table, .index = index
	};
	return lss_master_submit(node, &r, now_us);
}

int lss_master_activate_bit_timing_req(co_node *node, uint16_t delay_ms, uint64_t tag,
				       uint64_t now_us)
{
	lss_master_req r = { .service = LSS_SVC_ACTIVATE_BIT_TIMING,
			     .tag = tag,
			     .delay_ms = delay_ms };
	return lss_master_submit(node, &r, now_us);
}

int lss_master_store_req(co_node *node, uint64_t tag, uint64_t now_us)
{
	lss_master_req r = { .service = LSS_SVC_STORE, .tag = tag };

	return lss_master_submit(node, &r, now_us);
}

int lss_master_inquire_req(co_node *node, lss_master_service service, uint64_t tag, uint64_t now_us)
{
	lss_master_req r = { .service = service, .tag = tag };

	if (service < LSS_SVC_INQUIRE_VENDOR || service > LSS_SVC_INQUIRE_NODE_ID)
		return -EINVAL;
	return lss_master_submit(node, &r, now_us);
}

int lss_master_identify_remote_req(co_node *node, const lss_address *lo, const lss_address *hi,
				   uint64_t tag, uint64_t now_us)
{
	lss_master_req r = { .service = LSS_SVC_IDENTIFY_REMOTE, .tag = tag };

	if (!lo || !hi)
		return -EINVAL;
	r.addr = *lo;
	r.addr_high = *hi;
	return lss_master_submit(node, &r, now_us);
}

int lss_master_identify_non_configured_req(co_node *node, uint64_t tag, uint64_t now_us)
{
	lss_master_req r = { .service = LSS_SVC_IDENTIFY_NON_CONFIGURED, .tag = tag };
	return lss_master_submit(node, &r, now_us);
}

int lss_master_fastscan_req(co_node *node, const lss_address *known, uint8_t known_mask,
			    uint64_t tag, uint64_t now_us)
{
	lss_master_req r = { .service = LSS_SVC_FASTSCAN, .tag = tag, .known_mask = known_mask };

	if (known_mask && !known)
		return -EINVAL;
	if (known)
		r.addr = *known;
	return lss_master_submit(node, &r, now_us);
}

/* ---- lifetime ------------------------------------------------------------------------- */

int lss_master_init(co_node *node, struct lss_master **out)
{
	struct lss_master *m = calloc(1, sizeof(*m));
	int rx;

	if (!m)
		return -ENOMEM;
	m->node = node;
	m->timeout_ms = node->cfg.lss_timeout_ms ? node->cfg.lss_timeout_ms : DEFAULT_TIMEOUT_MS;
	m->step_ms = node->cfg.lss_scan_step_ms ? node->cfg.lss_scan_step_ms : DEFAULT_STEP_MS;
	m->q_len = node->cfg.lss_queue_len ? node->cfg.lss_queue_len : DEFAULT_QUEUE_LEN;
	m->deadline_us = CO_NO_DEADLINE;
	co_fsm_init(&m->fsm, &mst_def, m, LSS_MASTER_IDLE);
	m->queue = calloc(m->q_len, sizeof(*m->queue));
	if (!m->queue) {
		free(m);
		return -ENOMEM;
	}
	rx = co_rx_register(node, LSS_COBID_SLAVE, 0, lss_master_rx, m);
	if (rx < 0) {
		free(m->queue);
		free(m);
		return rx;
	}
	m->rx = rx;
	*out = m;
	return 0;
}

void lss_master_fini(struct lss_master *m)
{
	if (!m)
		return;
	(void)co_rx_unregister(m->node, m->rx);
	free(m->queue);
	free(m);
}
