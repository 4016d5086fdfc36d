/* SPDX-License-Identifier: MIT */
/*
 * core/pdo_scan.c - the PDO layout scan of one slave, as a core/fsm.h
 * table (contract and walk in pdo_scan.h).
 *
 * Every state that talks to the slave sends one SDO upload in on_enter and
 * decides in on_con; the confirmation carries no time, so it takes the
 * node's time of the call that produced it (node->now_us), as cfgmgr.c.
 */
#include "core/pdo_scan.h"

#include <errno.h>
#include <string.h>

#include "core/co_internal.h"
#include "core/crc16.h"
#include "core/od.h"
#include "core/pdo.h"
#include "core/sdo.h"
#include "core/sdo_client.h"

/* Tags of this module's requests: "PS" in the top bytes, node, sequence. */
#define TAG_BASE 0x5053000000000000ull
/* CiA 301 §7.4.7.1: RPDO dummy entries name the data types 0001h..0007h. */
#define DUMMY_INDEX_MAX 0x0007u
#define IDX_CDCF 0x1F22u /* CiA 302-3 concise DCF of node n */

static const co_fsm_def scan_fsm;

/* CiA 301 §7.5.2.35/37: sub 2 transmission type, 3 inhibit time (TPDO),
 * 5 event timer (an RPDO's deadline), 6 SYNC start value (TPDO); sub 4 is
 * reserved. */
static const uint8_t tpdo_comm_subs[] = { 2, 3, 5, 6 };
static const uint8_t rpdo_comm_subs[] = { 2, 5 };

const char *co_pdo_scan_state_to_string(int state)
{
	return co_fsm_state_name(&scan_fsm, state);
}

const char *co_pdo_scan_outcome_to_string(int outcome)
{
	switch (outcome) {
	case CO_PDO_SCAN_LEARNT:
		return "learnt";
	case CO_PDO_SCAN_ABORTED:
		return "aborted";
	case CO_PDO_SCAN_CANCELLED:
		return "cancelled";
	}
	return "?";
}

static uint16_t comm_index(const co_pdo_scan *job)
{
	return (uint16_t)((job->dir == CO_PDO_TX ? 0x1800u : 0x1400u) + job->n);
}

static uint16_t map_index(const co_pdo_scan *job)
{
	return (uint16_t)(comm_index(job) + 0x200u);
}

/* ---- requests ------------------------------------------------------------ */

static void on_sdo_con(void *arg, const co_ev_sdo_cli *con)
{
	co_pdo_scan *job = arg;

	if (!job->tag || con->tag != job->tag)
		return; /* a request of a scan that was cancelled */
	job->tag = 0;
	co_fsm_con(&job->fsm, con, job->line->node->now_us);
}

/* The scan stops on this object with this abort code. */
static int fail(co_pdo_scan *job, uint32_t abort, uint16_t index, uint8_t sub)
{
	job->res.abort = abort;
	job->res.index = index;
	job->res.sub = sub;
	return CO_PDO_SCAN_FAILED;
}

static int read_sub(co_pdo_scan *job, uint16_t index, uint8_t sub, uint64_t now_us)
{
	sdo_client_req r = {
		.upload = true,
		.node_id = job->node_id,
		.index = index,
		.sub = sub,
		.mode = SDO_MODE_AUTO,
		.timeout_ms = job->line->sdo_timeout_ms,
		.buf = job->rd,
		.cap = sizeof(job->rd),
		.con = on_sdo_con,
		.con_arg = job,
	};

	memset(job->rd, 0, sizeof(job->rd));
	r.tag = TAG_BASE | (uint64_t)job->node_id << 32 | ++job->seq;
	job->tag = r.tag;
	if (sdo_client_pool_submit(job->line->node, &r, now_us)) {
		job->tag = 0;
		return fail(job, SDO_AB_NO_RESOURCE, index, sub);
	}
	return CO_FSM_STAY;
}

static uint32_t value_of(const co_ev_sdo_cli *con)
{
	uint32_t v = 0;

	for (uint32_t i = 0; con->data && i < con->size && i < 4; i++)
		v |= (uint32_t)con->data[i] << (8 * i);
	return v;
}

/* The device has no such record or sub-index (CiA 301 aborts). */
static bool does_not_exist(uint32_t abort)
{
	return abort == SDO_AB_NO_OBJ || abort == SDO_AB_NO_SUB;
}

static int next_direction(co_pdo_scan *job)
{
	if (job->dir == CO_PDO_RX)
		return CO_PDO_SCAN_DONE;
	job->dir = CO_PDO_RX;
	job->n = 0;
	return CO_PDO_SCAN_COB;
}

/* ---- states ------------------------------------------------------------------ */

static int cob_enter(void *obj, uint64_t now_us)
{
	co_pdo_scan *job = obj;

	if (job->n >= CO_PDO_MAX)
		return next_direction(job);
	return read_sub(job, comm_index(job), 1, now_us);
}

static int cob_con(void *obj, const void *con, uint64_t now_us)
{
	co_pdo_scan *job = obj;
	const co_ev_sdo_cli *c = con;
	const co_pdo_layout_node *rec = co_pdo_layout_node_get(job->line->table, job->node_id);
	uint32_t cob = value_of(c);

	(void)now_us;
	if (does_not_exist(c->abort))
		return next_direction(job);
	if (c->abort)
		return fail(job, c->abort, c->index, c->sub);
	if (cob & CO_PDO_COB_INVALID) {
		job->res.invalid[job->dir]++;
		job->n++;
		return CO_PDO_SCAN_COB;
	}
	memset(&job->cur, 0, sizeof(job->cur));
	job->cur.nr = (uint16_t)(job->n + 1);
	job->cur.cob = cob;
	if (rec->n[job->dir] >= rec->cap) {
		/* no room: the table counts it, its mapping is not read */
		(void)co_pdo_layout_add(job->line->table, job->node_id, (co_pdo_dir)job->dir,
					&job->cur);
		job->n++;
		return CO_PDO_SCAN_COB;
	}
	job->step = 0;
	return CO_PDO_SCAN_COMM;
}

static const uint8_t *comm_subs(const co_pdo_scan *job, size_t *n)
{
	*n = job->dir == CO_PDO_TX ? sizeof(tpdo_comm_subs) : sizeof(rpdo_comm_subs);
	return job->dir == CO_PDO_TX ? tpdo_comm_subs : rpdo_comm_subs;
}

static int comm_enter(void *obj, uint64_t now_us)
{
	co_pdo_scan *job = obj;
	size_t n;
	const uint8_t *subs = comm_subs(job, &n);

	if (job->step >= n)
		return CO_PDO_SCAN_COUNT;
	return read_sub(job, comm_index(job), subs[job->step], now_us);
}

static int comm_con(void *obj, const void *con, uint64_t now_us)
{
	co_pdo_scan *job = obj;
	const co_ev_sdo_cli *c = con;
	uint32_t v = value_of(c);

	(void)now_us;
	if (c->abort == SDO_AB_NO_SUB)
		v = 0; /* the device does not have that parameter */
	else if (c->abort)
		return fail(job, c->abort, c->index, c->sub);
	switch (c->sub) {
	case 2:
		job->cur.tt = (uint8_t)v;
		break;
	case 3:
		job->cur.inhibit = (uint16_t)v;
		break;
	case 5:
		job->cur.event_ms = (uint16_t)v;
		break;
	default:
		job->cur.sync_start = (uint8_t)v;
		break;
	}
	job->step++;
	return CO_PDO_SCAN_COMM;
}

static int count_enter(void *obj, uint64_t now_us)
{
	co_pdo_scan *job = obj;

	return read_sub(job, map_index(job), 0, now_us);
}

static int count_con(void *obj, const void *con, uint64_t now_us)
{
	co_pdo_scan *job = obj;
	const co_ev_sdo_cli *c = con;
	uint32_t count = value_of(c);

	(void)now_us;
	if (c->abort)
		return fail(job, c->abort, c->index, c->sub);
	if (count > CO_PDO_MAX_MAP)
		return fail(job, SDO_AB_MAP_LEN, c->index, c->sub);
	job->count = (uint8_t)count;
	job->step = 1;
	job->bits = 0;
	return CO_PDO_SCAN_ENTRY;
}

static int entry_enter(void *obj, uint64_t now_us)
{
	co_pdo_scan *job = obj;

	if (job->step <= job->count)
		return read_sub(job, map_index(job), job->step, now_us);
	job->cur.n = job->count;
	(void)co_pdo_layout_add(job->line->table, job->node_id, (co_pdo_dir)job->dir, &job->cur);
	job->n++;
	return CO_PDO_SCAN_COB;
}

/* SDO cannot tell a data type: the node's list may (pdo_scan.h). */
static void type_entry(const co_pdo_scan *job, co_pdo_layout_entry *e)
{
	const co_pdo_scan_node *cfg = &job->line->cfg[job->node_id];
	const co_pdo_layout_type *t;

	if (job->dir == CO_PDO_RX && e->index >= 1 && e->index <= DUMMY_INDEX_MAX) {
		e->type = e->index;
		return;
	}
	t = co_pdo_layout_type_find(cfg->types, cfg->n_types, e->index, e->sub);
	if (!t)
		return;
	e->type = t->type;
	e->access = t->access;
}

static int entry_con(void *obj, const void *con, uint64_t now_us)
{
	co_pdo_scan *job = obj;
	const co_ev_sdo_cli *c = con;
	uint32_t v = value_of(c);
	co_pdo_layout_entry *e = &job->cur.map[job->step - 1];

	(void)now_us;
	if (c->abort)
		return fail(job, c->abort, c->index, c->sub);
	memset(e, 0, sizeof(*e));
	e->index = (uint16_t)(v >> 16);
	e->sub = (uint8_t)(v >> 8);
	e->bits = (uint8_t)v;
	job->bits = (uint16_t)(job->bits + e->bits);
	if (!e->bits || job->bits > CO_PDO_MAX_BITS)
		return fail(job, SDO_AB_MAP_LEN, c->index, c->sub);
	type_entry(job, e);
	job->step++;
	return CO_PDO_SCAN_ENTRY;
}

static void report(co_pdo_scan *job, uint8_t outcome, uint64_t now_us)
{
	const co_pdo_layout_node *rec = co_pdo_layout_node_get(job->line->table, job->node_id);

	job->res.outcome = outcome;
	if (job->starting)
		return; /* co_pdo_scan_line_step answers for itself */
	for (unsigned d = 0; d < 2; d++) {
		job->res.n[d] = rec->n[d];
		job->res.dropped[d] = rec->dropped[d];
	}
	if (job->line->done)
		job->line->done(job->line->done_ctx, &job->res, now_us);
}

static int done_enter(void *obj, uint64_t now_us)
{
	co_pdo_scan *job = obj;

	co_pdo_layout_commit(job->line->table, job->node_id, now_us);
	report(job, CO_PDO_SCAN_LEARNT, now_us);
	return CO_FSM_STAY;
}

static int failed_enter(void *obj, uint64_t now_us)
{
	report(obj, CO_PDO_SCAN_ABORTED, now_us);
	return CO_FSM_STAY;
}

static const co_fsm_state scan_states[CO_PDO_SCAN_N_STATES] = {
	[CO_PDO_SCAN_IDLE] = { .name = "idle" },
	[CO_PDO_SCAN_COB] = { .name = "cob-id", .on_enter = cob_enter, .on_con = cob_con },
	[CO_PDO_SCAN_COMM] = { .name = "communication",
			       .on_enter = comm_enter,
			       .on_con = comm_con },
	[CO_PDO_SCAN_COUNT] = { .name = "mapping-count",
				.on_enter = count_enter,
				.on_con = count_con },
	[CO_PDO_SCAN_ENTRY] = { .name = "mapping-entry",
				.on_enter = entry_enter,
				.on_con = entry_con },
	[CO_PDO_SCAN_DONE] = { .name = "done", .on_enter = done_enter },
	[CO_PDO_SCAN_FAILED] = { .name = "failed", .on_enter = failed_enter },
};

static const co_fsm_def scan_fsm = { "pdo_scan", scan_states, CO_PDO_SCAN_N_STATES };

bool co_pdo_scan_running(const co_pdo_scan *job)
{
	int s = co_fsm_state_of(&job->fsm);
	return job->fsm.def && s != CO_PDO_SCAN_IDLE && s != CO_PDO_SCAN_DONE &&
	       s != CO_PDO_SCAN_FAILED;
}

/* ---- the line ----------------------------------------------------------------- */

static uint16_t cdcf_crc(const co_node *node, uint8_t node_id)
{
	const co_od_entry *e = co_od_find(co_node_od(node), IDX_CDCF, node_id);

	return e && e->size ? crc16_ccitt(0, e->data, e->size) : 0;
}

void co_pdo_scan_line_init(co_pdo_scan_line *l, co_node *node, co_pdo_layout *table,
			   co_pdo_scan_done_fn done, void *done_ctx)
{
	l->node = node;
	l->table = table;
	l->done = done;
	l->done_ctx = done_ctx;
	for (unsigned n = 1; n <= 127; n++) {
		co_pdo_scan *job = &l->job[n - 1];
		memset(job, 0, sizeof(*job));
		job->line = l;
		job->node_id = (uint8_t)n;
		co_fsm_init(&job->fsm, &scan_fsm, job, CO_PDO_SCAN_IDLE);
		l->cdcf_crc[n] = l->cfg[n].from_file ? cdcf_crc(node, (uint8_t)n) : 0;
	}
}

/* A file layout holds while the node gets the concise DCF it had at
 * start-up (the configure step before this one restores it). */
static bool file_layout_holds(const co_pdo_scan_line *l, uint8_t node_id)
{
	return cdcf_crc(l->node, node_id) == l->cdcf_crc[node_id];
}

static void cancel(co_pdo_scan *job, uint64_t now_us);

int co_pdo_scan_line_step(void *ctx, uint8_t node_id, uint64_t now_us)
{
	co_pdo_scan_line *l = ctx;
	const co_pdo_scan_node *cfg;
	co_pdo_scan *job;

	if (!l || node_id < 1 || node_id > 127 || !co_pdo_layout_node_get(l->table, node_id))
		return 0;
	cfg = &l->cfg[node_id];
	job = &l->job[node_id - 1];
	if (cfg->from_file) {
		if (file_layout_holds(l, node_id))
			return 0;
		co_pdo_layout_invalidate(l->table, node_id);
		if (!cfg->scan_if_reconfigured)
			return 0;
	} else if (!cfg->scan) {
		return 0;
	}
	/* the boot started again (a request) while its scan ran: that scan
	 * belongs to the old boot */
	cancel(job, now_us);
	(void)co_pdo_layout_begin(l->table, node_id, CO_PDO_LAYOUT_SCAN);
	memset(&job->res, 0, sizeof(job->res));
	job->res.node_id = node_id;
	job->dir = CO_PDO_TX;
	job->n = 0;
	job->tag = 0;
	job->starting = true;
	co_fsm_goto(&job->fsm, CO_PDO_SCAN_COB, now_us);
	job->starting = false;
	/* the first request could not even be queued: the caller reports it */
	return co_fsm_state_of(&job->fsm) == CO_PDO_SCAN_FAILED ? -ENOBUFS : 1;
}

static void cancel(co_pdo_scan *job, uint64_t now_us)
{
	if (!co_pdo_scan_running(job))
		return;
	job->tag = 0; /* disowned: its answer is ignored */
	co_fsm_goto(&job->fsm, CO_PDO_SCAN_IDLE, now_us);
	report(job, CO_PDO_SCAN_CANCELLED, now_us);
}

void co_pdo_scan_line_on_event(co_pdo_scan_line *l, const co_event *ev, uint64_t now_us)
{
	uint8_t id = ev->u.errctrl.node;

	if (ev->kind != CO_EV_BOOTUP || id < 1 || id > 127 || !l->table)
		return;
	/* the device started again from its defaults: what was scanned may
	 * no longer be so (a file layout is restored by the configure step) */
	if (!l->cfg[id].from_file)
		co_pdo_layout_invalidate(l->table, id);
	cancel(&l->job[id - 1], now_us);
}

void co_pdo_scan_line_forget(co_pdo_scan_line *l, uint8_t node_id, uint64_t now_us)
{
	if (node_id < 1 || node_id > 127)
		return;
	cancel(&l->job[node_id - 1], now_us);
	if (l->table)
		co_pdo_layout_invalidate(l->table, node_id);
	l->cdcf_crc[node_id] = 0;
}

void co_pdo_scan_line_cancel_all(co_pdo_scan_line *l, uint64_t now_us)
{
	for (unsigned n = 0; n < 127; n++)
		cancel(&l->job[n], now_us);
}
