/* SPDX-License-Identifier: MIT */
/*
 * core/cfgmgr.c - the configuration manager's job on one slave (CiA 302-3
 * configuration download, verify configuration via 1020h, restore via
 * 1F8Ah), as a core/fsm.h table. Contract in cfgmgr.h.
 *
 * Every state that talks to the slave sends exactly one SDO request in
 * on_enter and decides in on_con. The confirmation callback carries no
 * time, so it takes the node's time of the current recv/tick call
 * (node->now_us) - the call that produced the confirmation.
 */
#include "core/cfgmgr.h"

#include <errno.h>
#include <string.h>

#include "core/co_internal.h"
#include "core/nmt.h"
#include "core/sdo.h"
#include "core/sdo_client.h"
#include "core/store.h"

/* Tags of this module's requests: 'CF' in the top byte, node, sequence. */
#define TAG_BASE 0xCF00000000000000ull

static const co_fsm_def cfgmgr_fsm;

const char *co_cfgmgr_state_to_string(int state)
{
	return co_fsm_state_name(&cfgmgr_fsm, state);
}

const char *co_cfgmgr_outcome_to_string(int outcome)
{
	switch (outcome) {
	case CO_CFGMGR_CONFIGURED:
		return "configured";
	case CO_CFGMGR_SKIPPED:
		return "skipped (1020h matches)";
	case CO_CFGMGR_FAILED_J:
		return "failed (J)";
	case CO_CFGMGR_CANCELLED:
		return "cancelled";
	}
	return "?";
}

/* ---- requests ------------------------------------------------------------ */

static void on_sdo_con(void *arg, const co_ev_sdo_cli *con)
{
	co_cfgmgr *job = arg;

	if (con->tag != job->tag)
		return; /* a request of a job that has moved on */
	job->tag = 0;
	co_fsm_con(&job->fsm, con, job->node->now_us);
}

/* Remember what is being done, for the failure report. */
static void mark(co_cfgmgr *job, uint32_t entry, uint16_t index, uint8_t sub)
{
	job->res.entry = entry;
	job->res.index = index;
	job->res.sub = sub;
}

/* Submit one request; returns 0, or the state to go to (FAILED) when it
 * cannot even be queued. */
static int submit(co_cfgmgr *job, bool upload, uint16_t index, uint8_t sub, const uint8_t *data,
		  uint32_t size, uint64_t now_us)
{
	sdo_client_req r = {
		.upload = upload,
		.node_id = job->p.node_id,
		.index = index,
		.sub = sub,
		.mode = SDO_MODE_AUTO,
		.timeout_ms = job->p.sdo_timeout_ms,
		.con = on_sdo_con,
		.con_arg = job,
	};
	int rc;

	if (upload) {
		r.buf = job->rd;
		r.cap = sizeof(job->rd);
	} else {
		r.data = data;
		r.size = size;
	}
	r.tag = TAG_BASE | (uint64_t)job->p.node_id << 32 | ++job->seq;
	job->tag = r.tag;
	if (job->p.channel >= 0)
		rc = sdo_client_submit(job->node, (uint8_t)job->p.channel, &r, now_us);
	else
		rc = sdo_client_pool_submit(job->node, &r, now_us);
	if (rc) {
		job->tag = 0;
		job->res.abort = SDO_AB_NO_RESOURCE;
		return CO_CFGMGR_FAILED;
	}
	return 0;
}

static int write_u32(co_cfgmgr *job, uint16_t index, uint8_t sub, uint32_t v, uint64_t now_us)
{
	int rc;

	mark(job, 0, index, sub);
	co_put_le32(job->wr, v);
	rc = submit(job, false, index, sub, job->wr, 4, now_us);
	return rc ? rc : CO_FSM_STAY;
}

static int read_u32(co_cfgmgr *job, uint16_t index, uint8_t sub, uint64_t now_us)
{
	int rc;

	mark(job, 0, index, sub);
	memset(job->rd, 0, sizeof(job->rd));
	rc = submit(job, true, index, sub, NULL, 0, now_us);
	return rc ? rc : CO_FSM_STAY;
}

/* A write finished: abort -> FAILED (the res fields say what), else next. */
static int after_write(co_cfgmgr *job, const co_ev_sdo_cli *con, int next)
{
	if (con->abort) {
		job->res.abort = con->abort;
		return CO_CFGMGR_FAILED;
	}
	return next;
}

/* Where to go once the concise DCF is written. */
static int after_download(co_cfgmgr *job)
{
	if (job->p.verify)
		return CO_CFGMGR_WRITE_DATE;
	return job->p.store ? CO_CFGMGR_STORE : CO_CFGMGR_DONE;
}

/* ---- states ------------------------------------------------------------------ */

static int restore_load_enter(void *obj, uint64_t now_us)
{
	co_cfgmgr *job = obj;

	job->res.restored = true;
	return write_u32(job, 0x1011, job->p.restore_sub, CO_STORE_SIG_LOAD, now_us);
}

static int restore_load_con(void *obj, const void *con, uint64_t now_us)
{
	(void)now_us;
	return after_write(obj, con, CO_CFGMGR_RESTORE_RESET);
}

static int restore_reset_enter(void *obj, uint64_t now_us)
{
	co_cfgmgr *job = obj;
	/* 1011h:2 restores the communication parameters only: a reset
	 * communication loads them; any other sub-index needs the application
	 * reset (reset node) to take effect. */
	uint8_t cs = job->p.restore_sub == 2 ? CO_NMT_CS_RESET_COMM : CO_NMT_CS_RESET_NODE;

	if (co_nmt_master_send(job->node, job->p.node_id, cs, now_us)) {
		job->res.abort = SDO_AB_NO_RESOURCE;
		return CO_CFGMGR_FAILED;
	}
	job->deadline_us = now_us + (uint64_t)job->p.bootup_wait_ms * 1000u;
	co_node_deadline_lower(job->node, job->deadline_us);
	return CO_FSM_STAY;
}

static int restore_reset_timeout(void *obj, uint64_t now_us)
{
	co_cfgmgr *job = obj;

	(void)now_us;
	job->res.abort = SDO_AB_TIMEOUT; /* no boot-up after the reset */
	return CO_CFGMGR_FAILED;
}

static void restore_reset_leave(void *obj, uint64_t now_us)
{
	co_cfgmgr *job = obj;

	(void)now_us;
	job->deadline_us = CO_NO_DEADLINE;
}

static int verify_date_enter(void *obj, uint64_t now_us)
{
	co_cfgmgr *job = obj;

	if (!job->p.verify)
		return CO_CFGMGR_DOWNLOAD;
	return read_u32(job, 0x1020, 1, now_us);
}

/* A 1020h read: equal -> `equal`, anything else (abort: 1020h not there;
 * another value; another size) -> the download. */
static int verify_con(co_cfgmgr *job, const co_ev_sdo_cli *con, uint32_t want, int equal)
{
	if (!con->abort && con->size == 4 && co_get_le32(job->rd) == want)
		return equal;
	return CO_CFGMGR_DOWNLOAD;
}

static int verify_date_con(void *obj, const void *con, uint64_t now_us)
{
	co_cfgmgr *job = obj;

	(void)now_us;
	return verify_con(job, con, job->p.date, CO_CFGMGR_VERIFY_TIME);
}

static int verify_time_enter(void *obj, uint64_t now_us)
{
	return read_u32(obj, 0x1020, 2, now_us);
}

static int verify_time_con(void *obj, const void *con, uint64_t now_us)
{
	co_cfgmgr *job = obj;

	(void)now_us;
	if (verify_con(job, con, job->p.time, CO_CFGMGR_DONE) == CO_CFGMGR_DONE) {
		job->res.outcome = CO_CFGMGR_SKIPPED;
		return CO_CFGMGR_DONE;
	}
	return CO_CFGMGR_DOWNLOAD;
}

/* Send the next entry of the concise DCF, or leave when all are written. */
static int download_next(co_cfgmgr *job, uint64_t now_us)
{
	int rc;

	if (!co_cdcf_iter_next(&job->it, &job->cur))
		return after_download(job);
	mark(job, job->cur.number, job->cur.index, job->cur.sub);
	rc = submit(job, false, job->cur.index, job->cur.sub, job->cur.data, job->cur.size, now_us);
	return rc ? rc : CO_FSM_STAY;
}

static int download_enter(void *obj, uint64_t now_us)
{
	co_cfgmgr *job = obj;

	/* checked in co_cfgmgr_start; an empty configuration has count 0 */
	if (!job->p.cdcf_len)
		return after_download(job);
	if (co_cdcf_iter_init(&job->it, job->p.cdcf, job->p.cdcf_len, NULL))
		return CO_CFGMGR_FAILED;
	return download_next(job, now_us);
}

static int download_con(void *obj, const void *con, uint64_t now_us)
{
	co_cfgmgr *job = obj;
	const co_ev_sdo_cli *c = con;

	if (c->abort) {
		job->res.abort = c->abort;
		return CO_CFGMGR_FAILED;
	}
	job->res.written++;
	return download_next(job, now_us);
}

static int write_date_enter(void *obj, uint64_t now_us)
{
	co_cfgmgr *job = obj;

	return write_u32(job, 0x1020, 1, job->p.date, now_us);
}

static int write_date_con(void *obj, const void *con, uint64_t now_us)
{
	(void)now_us;
	return after_write(obj, con, CO_CFGMGR_WRITE_TIME);
}

static int write_time_enter(void *obj, uint64_t now_us)
{
	co_cfgmgr *job = obj;

	return write_u32(job, 0x1020, 2, job->p.time, now_us);
}

static int write_time_con(void *obj, const void *con, uint64_t now_us)
{
	co_cfgmgr *job = obj;

	(void)now_us;
	return after_write(job, con, job->p.store ? CO_CFGMGR_STORE : CO_CFGMGR_DONE);
}

static int store_enter(void *obj, uint64_t now_us)
{
	return write_u32(obj, 0x1010, 1, CO_STORE_SIG_SAVE, now_us);
}

static int store_con(void *obj, const void *con, uint64_t now_us)
{
	(void)now_us;
	return after_write(obj, con, CO_CFGMGR_DONE);
}

static int done_enter(void *obj, uint64_t now_us)
{
	co_cfgmgr *job = obj;

	if (job->res.outcome != CO_CFGMGR_SKIPPED && job->res.outcome != CO_CFGMGR_CANCELLED)
		job->res.outcome = CO_CFGMGR_CONFIGURED;
	if (job->res.outcome != CO_CFGMGR_CANCELLED)
		mark(job, 0, 0, 0);
	job->res.abort = 0;
	if (job->p.done)
		job->p.done(job->p.done_ctx, &job->res, now_us);
	return CO_FSM_STAY;
}

static int failed_enter(void *obj, uint64_t now_us)
{
	co_cfgmgr *job = obj;

	job->res.outcome = CO_CFGMGR_FAILED_J;
	job->res.status = 'J';
	if (!job->res.abort)
		job->res.abort = SDO_AB_GENERAL;
	if (job->p.done)
		job->p.done(job->p.done_ctx, &job->res, now_us);
	return CO_FSM_STAY;
}

static const co_fsm_state cfgmgr_states[CO_CFGMGR_N_STATES] = {
	[CO_CFGMGR_IDLE] = { .name = "idle" },
	[CO_CFGMGR_RESTORE_LOAD] = { .name = "restore-load",
				     .on_enter = restore_load_enter,
				     .on_con = restore_load_con },
	[CO_CFGMGR_RESTORE_RESET] = { .name = "restore-reset",
				      .on_enter = restore_reset_enter,
				      .on_timeout = restore_reset_timeout,
				      .on_leave = restore_reset_leave },
	[CO_CFGMGR_VERIFY_DATE] = { .name = "verify-date",
				    .on_enter = verify_date_enter,
				    .on_con = verify_date_con },
	[CO_CFGMGR_VERIFY_TIME] = { .name = "verify-time",
				    .on_enter = verify_time_enter,
				    .on_con = verify_time_con },
	[CO_CFGMGR_DOWNLOAD] = { .name = "download",
				 .on_enter = download_enter,
				 .on_con = download_con },
	[CO_CFGMGR_WRITE_DATE] = { .name = "write-date",
				   .on_enter = write_date_enter,
				   .on_con = write_date_con },
	[CO_CFGMGR_WRITE_TIME] = { .name = "write-time",
				   .on_enter = write_time_enter,
				   .on_con = write_time_con },
	[CO_CFGMGR_STORE] = { .name = "store", .on_enter = store_enter, .on_con = store_con },
	[CO_CFGMGR_DONE] = { .name = "done", .on_enter = done_enter },
	[CO_CFGMGR_FAILED] = { .name = "failed", .on_enter = failed_enter },
};

static const co_fsm_def cfgmgr_fsm = {
	.name = "cfgmgr",
	.states = cfgmgr_states,
	.n_states = CO_CFGMGR_N_STATES,
};

/* ---- API ------------------------------------------------------------------------ */

bool co_cfgmgr_running(const co_cfgmgr *job)
{
	int s = job->fsm.def ? co_fsm_state_of(&job->fsm) : CO_CFGMGR_IDLE;

	return s != CO_CFGMGR_IDLE && s != CO_CFGMGR_DONE && s != CO_CFGMGR_FAILED;
}

int co_cfgmgr_start(co_cfgmgr *job, co_node *node, const co_cfgmgr_params *p, uint64_t now_us)
{
	if (!node || !p || p->node_id < 1 || p->node_id > 127 ||
	    (p->cdcf_len && co_cdcf_check(p->cdcf, p->cdcf_len, NULL, NULL)) ||
	    (p->channel >= 0 && p->channel >= sdo_client_channel_count(node)))
		return -EINVAL;
	if (co_cfgmgr_running(job))
		return -EBUSY;
	memset(job, 0, sizeof(*job));
	job->node = node;
	job->p = *p;
	if (!job->p.bootup_wait_ms)
		job->p.bootup_wait_ms = CO_CFGMGR_BOOTUP_WAIT_MS;
	job->deadline_us = CO_NO_DEADLINE;
	job->res.node_id = p->node_id;
	co_fsm_init(&job->fsm, &cfgmgr_fsm, job, CO_CFGMGR_IDLE);
	co_fsm_goto(&job->fsm, p->restore_sub ? CO_CFGMGR_RESTORE_LOAD : CO_CFGMGR_VERIFY_DATE,
		    now_us);
	return 0;
}

void co_cfgmgr_on_event(co_cfgmgr *job, const co_event *ev, uint64_t now_us)
{
	if (!job->fsm.def || co_fsm_state_of(&job->fsm) != CO_CFGMGR_RESTORE_RESET ||
	    ev->kind != CO_EV_BOOTUP || ev->u.errctrl.node != job->p.node_id)
		return;
	/* The slave is back with its restored defaults: configure it. */
	co_fsm_goto(&job->fsm, CO_CFGMGR_VERIFY_DATE, now_us);
}

uint64_t co_cfgmgr_next_deadline_us(const co_cfgmgr *job)
{
	return job->fsm.def ? job->deadline_us : CO_NO_DEADLINE;
}

uint64_t co_cfgmgr_tick(co_cfgmgr *job, uint64_t now_us)
{
	if (job->fsm.def && job->deadline_us != CO_NO_DEADLINE && now_us >= job->deadline_us) {
		job->deadline_us = CO_NO_DEADLINE;
		co_fsm_timeout(&job->fsm, now_us);
	}
	return co_cfgmgr_next_deadline_us(job);
}

int co_cfgmgr_cancel(co_cfgmgr *job, uint64_t now_us)
{
	uint64_t tag = job->tag;

	if (!co_cfgmgr_running(job))
		return -ENOENT;
	job->tag = 0; /* its confirmation is ignored from here on */
	if (tag)
		sdo_client_cancel_tag(job->node, tag, SDO_AB_GENERAL, now_us);
	job->res.outcome = CO_CFGMGR_CANCELLED;
	co_fsm_goto(&job->fsm, CO_CFGMGR_DONE, now_us);
	return 0;
}

/* ---- the configuration manager of a line ---------------------------------------- */

int co_od_add_cfgmgr_node(co_od *od, uint8_t node_id, uint32_t cdcf_cap)
{
	static const struct {
		uint16_t index;
		co_type type;
	} arrays[] = {
		{ CO_CFGMGR_IDX_DATE, CO_T_UNSIGNED32 },
		{ CO_CFGMGR_IDX_TIME, CO_T_UNSIGNED32 },
		{ CO_CFGMGR_IDX_RESTORE, CO_T_UNSIGNED8 },
	};
	co_od_desc d = {
		.index = CO_CFGMGR_IDX_CDCF,
		.sub = node_id,
		.obj_code = CO_OBJ_ARRAY,
		.type = CO_T_DOMAIN,
		.access = CO_ACC_RW,
		.max_size = cdcf_cap,
		.name = "ConciseDCF",
	};
	int rc;

	if (!od || node_id < 1 || node_id > 127 || !cdcf_cap)
		return -EINVAL;
	for (size_t i = 0; i < sizeof(arrays) / sizeof(arrays[0]); i++) {
		if (co_od_has_index(od, arrays[i].index))
			continue;
		rc = co_od_add_array(od, arrays[i].index, arrays[i].type, 127, CO_ACC_RW, 0);
		if (rc)
			return rc;
	}
	rc = co_od_ensure_num(od, CO_CFGMGR_IDX_CDCF, 0, CO_T_UNSIGNED8, CO_ACC_RO, 127,
			      CO_OBJ_ARRAY);
	if (rc || co_od_find(od, CO_CFGMGR_IDX_CDCF, node_id))
		return rc;
	return co_od_add(od, &d, NULL);
}

static uint32_t cdcf_check_write(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_cfgmgr_line *l = ctx;

	if (e->sub < 1 || e->sub > 127)
		return 0;
	if (co_cfgmgr_running(&l->job[e->sub - 1]))
		return SDO_AB_DEV_STATE; /* being configured */
	/* a streamed value is only seen in pieces: checked when used */
	if (a->data && a->size && co_cdcf_check(a->data, a->size, NULL, NULL))
		return SDO_AB_VALUE;
	return 0;
}

static const co_od_hooks cdcf_hooks = { .check_write = cdcf_check_write };

static void line_done(void *ctx, const co_cfgmgr_result *r, uint64_t now_us)
{
	co_cfgmgr_line *l = ctx;

	if (l->done)
		l->done(l->done_ctx, r, now_us);
}

void co_cfgmgr_line_init(co_cfgmgr_line *l, co_node *node, co_cfgmgr_done_fn done, void *done_ctx)
{
	co_od *od = co_node_od(node);

	memset(l, 0, sizeof(*l));
	l->node = node;
	l->channel = -1;
	l->done = done;
	l->done_ctx = done_ctx;
	for (unsigned n = 1; n <= 127; n++) {
		co_od_entry *e = co_od_find(od, CO_CFGMGR_IDX_CDCF, (uint8_t)n);
		if (e)
			co_od_entry_set_hooks(e, &cdcf_hooks, l);
	}
}

static uint32_t od_u32(const co_od *od, uint16_t index, uint8_t sub)
{
	uint32_t v = 0;

	if (co_od_get_u32(od, index, sub, &v))
		return 0;
	return v;
}

int co_cfgmgr_line_configure(void *ctx, uint8_t node_id, uint64_t now_us)
{
	co_cfgmgr_line *l = ctx;
	const co_od *od;
	const co_od_entry *e;
	co_cfgmgr_params p = { 0 };
	uint8_t restore = 0;
	int rc;

	if (!l || !l->node || node_id < 1 || node_id > 127)
		return -EINVAL;
	od = co_node_od(l->node);
	e = co_od_find(od, CO_CFGMGR_IDX_CDCF, node_id);
	p.node_id = node_id;
	if (e && e->size) {
		p.cdcf = e->data;
		p.cdcf_len = e->size;
	}
	p.date = od_u32(od, CO_CFGMGR_IDX_DATE, node_id);
	p.time = od_u32(od, CO_CFGMGR_IDX_TIME, node_id);
	p.verify = p.date || p.time; /* 0/0: always configure (CiA 302-3) */
	if ((od_u32(od, 0x1F81, node_id) & CO_CFGMGR_F81_RESTORE) &&
	    !co_od_get_u8(od, CO_CFGMGR_IDX_RESTORE, node_id, &restore))
		p.restore_sub = restore;
	p.store = l->store[node_id];
	if (!p.cdcf_len && !p.verify && !p.restore_sub)
		return 0;
	p.channel = l->channel;
	p.sdo_timeout_ms = l->sdo_timeout_ms;
	p.done = line_done;
	p.done_ctx = l;
	rc = co_cfgmgr_start(&l->job[node_id - 1], l->node, &p, now_us);
	return rc ? rc : 1;
}

void co_cfgmgr_line_on_event(co_cfgmgr_line *l, const co_event *ev, uint64_t now_us)
{
	if (ev->kind != CO_EV_BOOTUP || ev->u.errctrl.node < 1 || ev->u.errctrl.node > 127)
		return;
	co_cfgmgr_on_event(&l->job[ev->u.errctrl.node - 1], ev, now_us);
}

uint64_t co_cfgmgr_line_tick(co_cfgmgr_line *l, uint64_t now_us)
{
	uint64_t next = CO_NO_DEADLINE;

	for (unsigned n = 0; n < 127; n++) {
		uint64_t d = co_cfgmgr_tick(&l->job[n], now_us);
		if (d < next)
			next = d;
	}
	return next;
}

uint64_t co_cfgmgr_line_next_deadline_us(const co_cfgmgr_line *l)
{
	uint64_t next = CO_NO_DEADLINE;

	for (unsigned n = 0; n < 127; n++) {
		uint64_t d = co_cfgmgr_next_deadline_us(&l->job[n]);
		if (d < next)
			next = d;
	}
	return next;
}

void co_cfgmgr_line_cancel_all(co_cfgmgr_line *l, uint64_t now_us)
{
	for (unsigned n = 0; n < 127; n++)
		co_cfgmgr_cancel(&l->job[n], now_us);
}
