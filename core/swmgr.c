/* SPDX-License-Identifier: MIT */
/*
 * core/swmgr.c - the CiA 302-3 software manager's job on one slave
 * (software identification check, program stop / clear / download /
 * start / verify), as a core/fsm.h table. Contract in swmgr.h.
 *
 * Every state that talks to the slave sends exactly one SDO request in
 * on_enter and decides in on_con. Confirmations and the download source
 * carry no time: they take the node's time of the current recv/tick call
 * (node->now_us), the call that produced them.
 */
#include "core/swmgr.h"

#include <errno.h>
#include <string.h>

#include "core/co_internal.h"
#include "core/sdo.h"
#include "core/sdo_client.h"

/* Tags of this module's requests: 'SW' in the top byte, node, sequence. */
#define TAG_BASE 0x5700000000000000ull

static const co_fsm_def swmgr_fsm;

const char *co_swmgr_state_to_string(int state)
{
	return co_fsm_state_name(&swmgr_fsm, state);
}

const char *co_swmgr_outcome_to_string(int outcome)
{
	switch (outcome) {
	case CO_SWMGR_UNCHANGED:
		return "unchanged (1F56h matches)";
	case CO_SWMGR_UPDATED:
		return "updated";
	case CO_SWMGR_FAILED_STATUS:
		return "failed";
	case CO_SWMGR_CANCELLED:
		return "cancelled";
	}
	return "?";
}

const char *co_swmgr_program_to_string(uint8_t program)
{
	switch (program) {
	case CO_SWMGR_PROG_STOPPED:
		return "stopped";
	case CO_SWMGR_PROG_STARTED:
		return "started";
	case CO_SWMGR_PROG_NONE:
		return "no program";
	case CO_SWMGR_PROGRAM_UNKNOWN:
		return "unknown";
	}
	return "?";
}

bool co_swmgr_program_down(const co_swmgr_result *r)
{
	return r->program != CO_SWMGR_PROGRAM_UNKNOWN && r->program != CO_SWMGR_PROG_STARTED;
}

void co_swmgr_result_finding(const co_swmgr_result *r, uint16_t *index, uint8_t *sub,
			     uint32_t *value)
{
	if (co_swmgr_program_down(r) && (r->look_only || r->index == CO_SWMGR_IDX_CONTROL)) {
		*index = CO_SWMGR_IDX_CONTROL;
		*sub = 1;
		*value = r->program;
		return;
	}
	*index = r->index;
	*sub = r->sub;
	*value = r->found;
}

/* ---- requests ------------------------------------------------------------ */

static void on_sdo_con(void *arg, const co_ev_sdo_cli *con)
{
	co_swmgr *job = arg;

	if (con->tag != job->tag)
		return; /* a request of a job that has moved on */
	job->tag = 0;
	co_fsm_con(&job->fsm, con, job->node->now_us);
}

/* The SDO client pulls the image through here: count it, report progress. */
static int image_src(void *ctx, uint32_t offset, uint8_t *buf, uint32_t len)
{
	co_swmgr *job = ctx;
	int n;

	if (offset >= job->image_size)
		return 0;
	if (len > job->image_size - offset)
		len = job->image_size - offset;
	n = job->p.source.read(job->p.source.ctx, job->p.node_id, offset, buf, len);
	if (n < 0)
		return n;
	job->res.bytes = offset + (uint32_t)n;
	if (job->p.progress && job->res.bytes >= job->next_progress) {
		job->p.progress(job->p.progress_ctx, job->p.node_id, job->res.bytes,
				job->image_size, job->node->now_us);
		while (job->next_progress <= job->res.bytes)
			job->next_progress += job->p.progress_step;
		if (job->next_progress > job->image_size)
			job->next_progress = job->image_size;
	}
	return n;
}

static void mark(co_swmgr *job, uint16_t index, uint8_t sub)
{
	job->res.step = (uint8_t)co_fsm_state_of(&job->fsm);
	job->res.index = index;
	job->res.sub = sub;
}

/* Submit one request; 0, or FAILED (I) when it cannot even be queued. */
static int submit(co_swmgr *job, sdo_client_req *r, uint64_t now_us)
{
	int rc;

	r->node_id = job->p.node_id;
	r->timeout_ms = job->p.sdo_timeout_ms;
	r->con = on_sdo_con;
	r->con_arg = job;
	r->tag = TAG_BASE | (uint64_t)job->p.node_id << 32 | ++job->seq;
	mark(job, r->index, r->sub);
	job->tag = r->tag;
	if (job->p.channel >= 0)
		rc = sdo_client_submit(job->node, (uint8_t)job->p.channel, r, now_us);
	else
		rc = sdo_client_pool_submit(job->node, r, now_us);
	if (rc) {
		job->tag = 0;
		job->res.abort = SDO_AB_NO_RESOURCE;
		job->res.status = 'I';
		return CO_SWMGR_FAILED;
	}
	return CO_FSM_STAY;
}

/* Read sub 1 of the slave's 1F51h (program control) or 1F56h (software
 * identification) into job->rd. */
static int read_sub1(co_swmgr *job, uint16_t index, uint64_t now_us)
{
	sdo_client_req r = { .upload = true,
			     .index = index,
			     .sub = 1,
			     .mode = SDO_MODE_AUTO,
			     .buf = job->rd,
			     .cap = sizeof(job->rd) };

	memset(job->rd, 0, sizeof(job->rd));
	return submit(job, &r, now_us);
}

static int write_control(co_swmgr *job, uint8_t cmd, uint64_t now_us)
{
	sdo_client_req r = { .index = CO_SWMGR_IDX_CONTROL,
			     .sub = 1,
			     .mode = SDO_MODE_AUTO,
			     .data = job->wr,
			     .size = 1 };

	job->wr[0] = cmd;
	return submit(job, &r, now_us);
}

/* A step finished: an abort fails the update (I), else go on. */
static int after(co_swmgr *job, const co_ev_sdo_cli *con, int next)
{
	if (con->abort) {
		job->res.abort = con->abort;
		job->res.status = 'I';
		return CO_SWMGR_FAILED;
	}
	return next;
}

/* The identification the slave reports; an abort or a wrong size fails. */
static int got_id(co_swmgr *job, const co_ev_sdo_cli *con)
{
	if (con->abort || con->size != 4) {
		job->res.abort = con->abort ? con->abort : SDO_AB_TYPE_LEN;
		job->res.status = 'I';
		return -1;
	}
	job->res.found = co_get_le32(job->rd);
	return 0;
}

/* ---- states ------------------------------------------------------------------ */

/* An update is needed (a program that does not run, or another
 * identification): allowed and possible, or H / G. */
static int update_needed(co_swmgr *job, uint16_t index, uint8_t sub)
{
	if (!job->p.update_allowed) {
		mark(job, index, sub);
		job->res.status = 'H';
		return CO_SWMGR_FAILED;
	}
	if (!job->image_size) {
		mark(job, CO_SWMGR_IDX_IMAGE, job->p.node_id);
		job->res.status = 'G';
		return CO_SWMGR_FAILED;
	}
	return CO_SWMGR_STOP;
}

static int program_enter(void *obj, uint64_t now_us)
{
	co_swmgr *job = obj;

	if (job->p.force) /* a manual update: no check */
		return CO_SWMGR_STOP;
	return read_sub1(job, CO_SWMGR_IDX_CONTROL, now_us);
}

/* CiA 302-3 1F51h:1: after a download cut short (the manager restarted,
 * the line went down) the slave sits in its boot loader with a cleared or
 * stopped program, and its 1F56h:1 may still name the old one. */
static int program_con(void *obj, const void *con, uint64_t now_us)
{
	co_swmgr *job = obj;
	const co_ev_sdo_cli *c = con;

	(void)now_us;
	if (c->abort || c->size != 1) /* no program control: nothing to see */
		return job->p.look_only ? CO_SWMGR_DONE : CO_SWMGR_CHECK;
	job->res.program = job->rd[0];
	if (job->p.look_only)
		return CO_SWMGR_DONE;
	if (job->res.program == CO_SWMGR_PROG_STARTED)
		return CO_SWMGR_CHECK;
	return update_needed(job, CO_SWMGR_IDX_CONTROL, 1);
}

static int check_enter(void *obj, uint64_t now_us)
{
	return read_sub1(obj, CO_SWMGR_IDX_ID, now_us);
}

static int check_con(void *obj, const void *con, uint64_t now_us)
{
	co_swmgr *job = obj;

	(void)now_us;
	if (got_id(job, con))
		return CO_SWMGR_FAILED;
	if (job->res.found == job->p.expected)
		return CO_SWMGR_DONE;
	return update_needed(job, CO_SWMGR_IDX_ID, 1);
}

static int stop_enter(void *obj, uint64_t now_us)
{
	co_swmgr *job = obj;

	job->res.downloaded = true;
	return write_control(job, CO_SWMGR_CTL_STOP, now_us);
}

static int stop_con(void *obj, const void *con, uint64_t now_us)
{
	(void)now_us;
	return after(obj, con, CO_SWMGR_CLEAR);
}

static int clear_enter(void *obj, uint64_t now_us)
{
	return write_control(obj, CO_SWMGR_CTL_CLEAR, now_us);
}

static int clear_con(void *obj, const void *con, uint64_t now_us)
{
	(void)now_us;
	return after(obj, con, CO_SWMGR_DOWNLOAD);
}

static int download_enter(void *obj, uint64_t now_us)
{
	co_swmgr *job = obj;
	sdo_client_req r = { .index = CO_SWMGR_IDX_DATA,
			     .sub = 1,
			     .mode = SDO_MODE_BLOCK,
			     .size = job->image_size,
			     .src = image_src,
			     .ctx = job };

	job->res.bytes = 0;
	job->next_progress = job->p.progress_step < job->image_size ? job->p.progress_step
								    : job->image_size;
	return submit(job, &r, now_us);
}

static int download_con(void *obj, const void *con, uint64_t now_us)
{
	co_swmgr *job = obj;
	const co_ev_sdo_cli *c = con;

	(void)now_us;
	if (!c->abort)
		job->res.mode = c->mode;
	return after(job, c, CO_SWMGR_START);
}

static int start_enter(void *obj, uint64_t now_us)
{
	return write_control(obj, CO_SWMGR_CTL_START, now_us);
}

static int start_con(void *obj, const void *con, uint64_t now_us)
{
	(void)now_us;
	return after(obj, con, CO_SWMGR_VERIFY);
}

static int verify_enter(void *obj, uint64_t now_us)
{
	return read_sub1(obj, CO_SWMGR_IDX_ID, now_us);
}

static int verify_con(void *obj, const void *con, uint64_t now_us)
{
	co_swmgr *job = obj;

	(void)now_us;
	if (got_id(job, con))
		return CO_SWMGR_FAILED;
	if (job->p.expected && job->res.found != job->p.expected) {
		job->res.status = 'I'; /* the new program is not the expected one */
		job->res.abort = 0;
		return CO_SWMGR_FAILED;
	}
	return CO_SWMGR_DONE;
}

static int done_enter(void *obj, uint64_t now_us)
{
	co_swmgr *job = obj;

	if (job->res.outcome != CO_SWMGR_CANCELLED) {
		job->res.outcome = job->res.downloaded ? CO_SWMGR_UPDATED : CO_SWMGR_UNCHANGED;
		mark(job, 0, 0);
		job->res.step = 0;
		job->res.abort = 0;
	}
	if (job->p.done)
		job->p.done(job->p.done_ctx, &job->res, now_us);
	return CO_FSM_STAY;
}

static int failed_enter(void *obj, uint64_t now_us)
{
	co_swmgr *job = obj;

	job->res.outcome = CO_SWMGR_FAILED_STATUS;
	if (!job->res.status)
		job->res.status = 'I';
	if (job->p.done && job->started)
		job->p.done(job->p.done_ctx, &job->res, now_us);
	return CO_FSM_STAY;
}

static const co_fsm_state swmgr_states[CO_SWMGR_N_STATES] = {
	[CO_SWMGR_IDLE] = { .name = "idle" },
	[CO_SWMGR_PROGRAM] = { .name = "program",
			       .on_enter = program_enter,
			       .on_con = program_con },
	[CO_SWMGR_CHECK] = { .name = "check", .on_enter = check_enter, .on_con = check_con },
	[CO_SWMGR_STOP] = { .name = "stop", .on_enter = stop_enter, .on_con = stop_con },
	[CO_SWMGR_CLEAR] = { .name = "clear", .on_enter = clear_enter, .on_con = clear_con },
	[CO_SWMGR_DOWNLOAD] = { .name = "download",
				.on_enter = download_enter,
				.on_con = download_con },
	[CO_SWMGR_START] = { .name = "start", .on_enter = start_enter, .on_con = start_con },
	[CO_SWMGR_VERIFY] = { .name = "verify", .on_enter = verify_enter, .on_con = verify_con },
	[CO_SWMGR_DONE] = { .name = "done", .on_enter = done_enter },
	[CO_SWMGR_FAILED] = { .name = "failed", .on_enter = failed_enter },
};

static const co_fsm_def swmgr_fsm = {
	.name = "swmgr",
	.states = swmgr_states,
	.n_states = CO_SWMGR_N_STATES,
};

/* ---- API ------------------------------------------------------------------------ */

bool co_swmgr_running(const co_swmgr *job)
{
	int s = job->fsm.def ? co_fsm_state_of(&job->fsm) : CO_SWMGR_IDLE;

	return s != CO_SWMGR_IDLE && s != CO_SWMGR_DONE && s != CO_SWMGR_FAILED;
}

int co_swmgr_start(co_swmgr *job, co_node *node, const co_swmgr_params *p, uint64_t now_us)
{
	uint32_t size;

	if (!node || !p || p->node_id < 1 || p->node_id > 127 ||
	    (p->source.read && !p->source.size) ||
	    (p->channel >= 0 && p->channel >= sdo_client_channel_count(node)))
		return -EINVAL;
	if (co_swmgr_running(job))
		return -EBUSY;
	size = p->source.size && p->source.read ? p->source.size(p->source.ctx, p->node_id) : 0;
	if ((!p->force && !p->look_only && !p->expected) || (p->force && !size))
		return -ENOENT; /* G: nothing to compare with, or nothing to load */
	memset(job, 0, sizeof(*job));
	job->node = node;
	job->p = *p;
	job->image_size = size;
	if (!job->p.progress_step)
		job->p.progress_step = CO_SWMGR_PROGRESS_STEP;
	job->res.node_id = p->node_id;
	job->res.expected = p->expected;
	job->res.program = CO_SWMGR_PROGRAM_UNKNOWN;
	job->res.look_only = p->look_only;
	co_fsm_init(&job->fsm, &swmgr_fsm, job, CO_SWMGR_IDLE);
	co_fsm_goto(&job->fsm, CO_SWMGR_PROGRAM, now_us);
	if (co_fsm_state_of(&job->fsm) == CO_SWMGR_FAILED)
		return -EAGAIN; /* the first request could not be queued */
	job->started = true;
	return 0;
}

int co_swmgr_cancel(co_swmgr *job, uint64_t now_us)
{
	uint64_t tag = job->tag;

	if (!co_swmgr_running(job))
		return -ENOENT;
	job->tag = 0; /* its confirmation is ignored from here on */
	if (tag)
		sdo_client_cancel_tag(job->node, tag, SDO_AB_GENERAL, now_us);
	job->res.outcome = CO_SWMGR_CANCELLED;
	co_fsm_goto(&job->fsm, CO_SWMGR_DONE, now_us);
	return 0;
}

/* ---- the software manager of a line -------------------------------------------- */

int co_od_add_swmgr_defaults(co_od *od)
{
	if (!od)
		return -EINVAL;
	if (co_od_has_index(od, CO_SWMGR_IDX_EXPECTED))
		return 0;
	return co_od_add_array(od, CO_SWMGR_IDX_EXPECTED, CO_T_UNSIGNED32, 127, CO_ACC_RW, 0);
}

void co_swmgr_line_init(co_swmgr_line *l, co_node *node, const co_swmgr_source *source,
			co_swmgr_done_fn done, void *done_ctx)
{
	memset(l, 0, sizeof(*l));
	l->node = node;
	if (source)
		l->source = *source;
	l->channel = -1;
	l->done = done;
	l->done_ctx = done_ctx;
}

static uint32_t od_u32(const co_od *od, uint16_t index, uint8_t sub)
{
	uint32_t v = 0;

	if (co_od_get_u32(od, index, sub, &v))
		return 0;
	return v;
}

static int line_start(co_swmgr_line *l, uint8_t node_id, bool force, const co_swmgr_source *image,
		      uint32_t expected, uint64_t now_us)
{
	const co_od *od = co_node_od(l->node);
	uint32_t a = od_u32(od, 0x1F81, node_id);
	co_swmgr_params p = {
		.node_id = node_id,
		.expected = expected ? expected : od_u32(od, CO_SWMGR_IDX_EXPECTED, node_id),
		.update_allowed = force || (a & CO_SWMGR_F81_UPDATE),
		.force = force,
		.look_only = !force && !(a & CO_SWMGR_F81_CHECK),
		.source = image ? *image : l->source,
		.progress = l->progress,
		.progress_ctx = l->progress_ctx,
		.channel = l->channel,
		.sdo_timeout_ms = l->sdo_timeout_ms,
		.done = l->done,
		.done_ctx = l->done_ctx,
	};

	return co_swmgr_start(&l->job[node_id - 1], l->node, &p, now_us);
}

int co_swmgr_line_check(void *ctx, uint8_t node_id, uint64_t now_us)
{
	co_swmgr_line *l = ctx;
	int rc;

	if (!l || !l->node || node_id < 1 || node_id > 127)
		return -EINVAL;
	rc = line_start(l, node_id, false, NULL, 0, now_us);
	return rc ? rc : 1;
}

int co_swmgr_line_program(co_swmgr_line *l, uint8_t node_id, const co_swmgr_source *image,
			  uint32_t expected, uint64_t now_us)
{
	if (!l || !l->node || node_id < 1 || node_id > 127)
		return -EINVAL;
	return line_start(l, node_id, true, image, expected, now_us);
}

void co_swmgr_line_cancel_all(co_swmgr_line *l, uint64_t now_us)
{
	for (unsigned n = 0; n < 127; n++)
		co_swmgr_cancel(&l->job[n], now_us);
}
