/* SPDX-License-Identifier: MIT */
/*
 * manager/manager_ext.c - see manager_ext.h. Everything here runs on the
 * line thread (attach/detach while it does not run): each line owns its
 * manager alone.
 */
#include "manager/manager_ext.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/cfgmgr.h"
#include "core/manager.h"
#include "core/nmt.h"
#include "core/pdo_scan.h"
#include "core/sdo.h"
#include "core/swmgr.h"
#include "lines/log.h"
#include "mailbox/proto.h"

/*
 * A manual program update asked for over the mailbox (MBX_CMD_MGR_PROGRAM):
 * the request waits here until the node's software manager job ends. A
 * chunked image stays in the mailbox's transfer slot until the request is
 * answered; one that came in a single message lives only during dispatch
 * and is copied into `copy` (the largest single-message image, allocated
 * at setup). Two at a time per line, like the mailbox's default transfer
 * slots: more -> BUSY.
 */
#define MGR_PROGRAM_MAX 2

struct mgr_program {
	bool used;
	uint8_t node;
	mbx_reply_to reply;
	const uint8_t *image;
	uint32_t size;
	uint8_t *copy;
};

struct mgr_line {
	mgr_ext_line_params lc;
	co_manager *mgr;
	co_cfgmgr_line cfgm;
	co_swmgr_line swm;
	co_pdo_scan_line scan;
	line *l; /* while attached: progress events go to its mailbox */
	struct mgr_program prog[MGR_PROGRAM_MAX];
	uint32_t node_changes, node_changes_refused; /* nodes at run time */
	size_t copy_cap;                             /* bytes of each prog[].copy */
	mgr_ext_device *devices;                     /* lc.devices, owned */
};

struct mgr_ext {
	unsigned n_lines;
	struct mgr_line lines[MGR_EXT_LINES_MAX];
};

static struct mgr_program *program_of(struct mgr_line *ml, uint8_t node_id)
{
	for (unsigned i = 0; i < MGR_PROGRAM_MAX; i++)
		if (ml->prog[i].used && ml->prog[i].node == node_id)
			return &ml->prog[i];
	return NULL;
}

/* The 302-3 job ended: the boot slave process goes on (J on failure). */
static void cfgm_done(void *ctx, const co_cfgmgr_result *r, uint64_t now_us)
{
	struct mgr_line *ml = ctx;
	uint32_t abort = r->outcome == CO_CFGMGR_FAILED_J || r->outcome == CO_CFGMGR_CANCELLED
				 ? (r->abort ? r->abort : SDO_AB_GENERAL)
				 : 0;
	if (r->outcome == CO_CFGMGR_FAILED_J)
		cogw_log(COGW_LOG_ERR,
			 "line %s: node %u: configuration failed at entry %u (%04X:%02X): abort "
			 "%08X (%s)",
			 ml->lc.name, r->node_id, (unsigned)r->entry, r->index, r->sub,
			 (unsigned)r->abort, sdo_abort_to_string(r->abort));
	else if (r->outcome == CO_CFGMGR_CONFIGURED)
		cogw_log(COGW_LOG_INFO, "line %s: node %u: configured (%u entries%s)", ml->lc.name,
			 r->node_id, (unsigned)r->written,
			 r->restored ? ", defaults restored first" : "");
	else if (r->outcome == CO_CFGMGR_SKIPPED)
		cogw_log(COGW_LOG_INFO,
			 "line %s: node %u: configuration unchanged (1020h matches 1F26h/1F27h)",
			 ml->lc.name, r->node_id);
	if (ml->mgr)
		(void)co_manager_configure_done(ml->mgr, r->node_id, abort, r->index, r->sub,
						abort ? r->entry : r->written, now_us);
}

/* The PDO layout step ended: the learnt layout in the log (one line per
 * PDO), the boot slave process goes on (the boot event reports it). */
static void scan_done(void *ctx, const co_pdo_scan_result *r, uint64_t now_us)
{
	struct mgr_line *ml = ctx;
	uint32_t abort = r->outcome == CO_PDO_SCAN_LEARNT ? 0
			 : r->abort                       ? r->abort
							  : SDO_AB_GENERAL;

	/* cancelled by the node's boot-up (its boot starts again) or by the
	 * line stopping: nothing to report, nobody waits for it */
	if (r->outcome == CO_PDO_SCAN_CANCELLED)
		return;
	if (r->outcome == CO_PDO_SCAN_LEARNT) {
		cogw_log_pdo_layout(ml->lc.name, ml->scan.table, r->node_id);
		cogw_log(r->dropped[CO_PDO_TX] || r->dropped[CO_PDO_RX] ? COGW_LOG_WARNING
									: COGW_LOG_INFO,
			 "line %s: node %u: PDO layout learnt by SDO: %u TPDOs, %u RPDOs (%u and "
			 "%u invalid; %u and %u beyond pdo_scan_max, not kept)",
			 ml->lc.name, r->node_id, r->n[CO_PDO_TX], r->n[CO_PDO_RX],
			 r->invalid[CO_PDO_TX], r->invalid[CO_PDO_RX], r->dropped[CO_PDO_TX],
			 r->dropped[CO_PDO_RX]);
	} else if (r->outcome == CO_PDO_SCAN_ABORTED) {
		cogw_log(COGW_LOG_WARNING,
			 "line %s: node %u: PDO layout not learnt: %04X:%02X abort %08X (%s); the "
			 "boot goes on",
			 ml->lc.name, r->node_id, r->index, r->sub, (unsigned)r->abort,
			 sdo_abort_to_string(r->abort));
	}
	if (ml->mgr)
		(void)co_manager_pdo_layout_done(
			ml->mgr, r->node_id, abort, r->index, r->sub,
			(uint32_t)r->n[CO_PDO_TX] | (uint32_t)r->n[CO_PDO_RX] << 16,
			(uint32_t)r->dropped[CO_PDO_TX] | (uint32_t)r->dropped[CO_PDO_RX] << 16,
			now_us);
}

/* 1F58h:n: the images read from the files of nodes[].program at load. */
static const mgr_ext_node *node_of(const struct mgr_line *ml, uint8_t id)
{
	for (size_t i = 0; i < ml->lc.n_nodes; i++)
		if (ml->lc.nodes[i].id == id)
			return &ml->lc.nodes[i];
	return NULL;
}

static uint32_t image_size(void *ctx, uint8_t node_id)
{
	const mgr_ext_node *n = node_of(ctx, node_id);
	return n && n->program ? (uint32_t)n->program_len : 0;
}

static int image_read(void *ctx, uint8_t node_id, uint32_t offset, uint8_t *buf, uint32_t len)
{
	const mgr_ext_node *n = node_of(ctx, node_id);
	if (!n || !n->program || offset > n->program_len)
		return -EINVAL;
	if (len > n->program_len - offset)
		len = (uint32_t)(n->program_len - offset);
	memcpy(buf, n->program + offset, len);
	return (int)len;
}

/* The image of a manual update (MBX_CMD_MGR_PROGRAM), read from the
 * request's data. */
static uint32_t program_size(void *ctx, uint8_t node_id)
{
	const struct mgr_program *p = ctx;
	return p->used && p->node == node_id ? p->size : 0;
}

static int program_read(void *ctx, uint8_t node_id, uint32_t offset, uint8_t *buf, uint32_t len)
{
	const struct mgr_program *p = ctx;
	if (!p->used || p->node != node_id || offset > p->size)
		return -EINVAL;
	if (len > p->size - offset)
		len = p->size - offset;
	memcpy(buf, p->image + offset, len);
	return (int)len;
}

/* Progress of a program download: an MGR_NODE event "program" (value =
 * bytes sent, expected = image size; corr = the MGR_PROGRAM request of a
 * manual update, 0 during the boot) and a log line at the end. */
static void swm_progress(void *ctx, uint8_t node_id, uint32_t sent, uint32_t total, uint64_t now_us)
{
	struct mgr_line *ml = ctx;
	const struct mgr_program *p = program_of(ml, node_id);
	mbx_ev_mgr w = {
		.node = node_id, .what = CO_MGR_NODE_PROGRAM, .value = sent, .expected = total
	};
	(void)now_us;
	if (sent == total)
		cogw_log(COGW_LOG_INFO, "line %s: node %u: program image sent (%u bytes)",
			 ml->lc.name, node_id, (unsigned)total);
	if (ml->l)
		(void)mbx_server_publish(line_mbx(ml->l), MBX_EV_MGR_NODE, p ? p->reply.corr : 0,
					 &w, sizeof w);
}

/* A manual update ended: answer its requester (a gone client's answer is
 * discarded by the mailbox) and free the entry. */
static void program_answer(struct mgr_line *ml, struct mgr_program *p, const co_swmgr_result *r)
{
	mbx_mgr_program_resp a = {
		.status = r->outcome == CO_SWMGR_UPDATED ? 0
			  : r->status                    ? r->status
							 : 'I',
		.step = r->step,
		.index = r->index,
		.sub = r->sub,
		.mode = r->mode,
		.abort = r->outcome == CO_SWMGR_CANCELLED && !r->abort ? SDO_AB_GENERAL : r->abort,
		.found = r->found,
		.expected = r->expected,
		.bytes = r->bytes,
	};
	if (ml->l)
		(void)mbx_server_respond(line_mbx(ml->l), &p->reply, 0, 0, &a, sizeof a);
	p->used = false;
	p->image = NULL;
}

/* The 302-3 software check/update ended: the boot slave process goes on
 * (G, H or I on failure). */
static void swm_done(void *ctx, const co_swmgr_result *r, uint64_t now_us)
{
	struct mgr_line *ml = ctx;
	struct mgr_program *p = program_of(ml, r->node_id);
	char status = r->outcome == CO_SWMGR_FAILED_STATUS ? r->status
		      : r->outcome == CO_SWMGR_CANCELLED   ? 'I'
							   : 0;
	uint16_t index;
	uint8_t sub;
	uint32_t value;
	co_swmgr_result_finding(r, &index, &sub, &value);
	if (status)
		cogw_log(COGW_LOG_ERR,
			 "line %s: node %u: software %c (%s) at %04X:%02X: abort %08X, 1F56h:1 = "
			 "%08X, expected %08X, program %s (1F51h:1)",
			 ml->lc.name, r->node_id, status, co_mgr_status_to_string(status), r->index,
			 r->sub, (unsigned)r->abort, (unsigned)r->found, (unsigned)r->expected,
			 co_swmgr_program_to_string(r->program));
	else if (r->look_only && co_swmgr_program_down(r))
		/* CiA 302-3: a program that does not run after a download was cut
		 * short (docs/config.md "Program state") */
		cogw_log(COGW_LOG_WARNING,
			 "line %s: node %u: its program does not run (1F51h:1 = %u, %s): a program "
			 "download cut short? No software_id is configured to check or restore it",
			 ml->lc.name, r->node_id, r->program,
			 co_swmgr_program_to_string(r->program));
	else if (r->look_only)
		; /* software not checked, program running or without program control */
	else if (r->outcome == CO_SWMGR_UPDATED)
		cogw_log(COGW_LOG_INFO,
			 "line %s: node %u: program updated (%u bytes), software %08X", ml->lc.name,
			 r->node_id, (unsigned)r->bytes, (unsigned)r->found);
	else
		cogw_log(COGW_LOG_INFO, "line %s: node %u: software %08X as expected", ml->lc.name,
			 r->node_id, (unsigned)r->found);
	if (p) { /* a manual update, not the boot's check software step */
		program_answer(ml, p, r);
		return;
	}
	if (ml->mgr)
		(void)co_manager_software_done(ml->mgr, r->node_id, status, r->abort, index, sub,
					       value, now_us);
}

static int mgr_attach(void *ctx, line *l)
{
	struct mgr_line *ml = ctx;
	co_node *node = line_node(l);
	co_manager_config c = ml->lc.mgr;
	const co_swmgr_source src = { .size = image_size, .read = image_read, .ctx = ml };
	int rc;

	c.configure = co_cfgmgr_line_configure;
	c.configure_ctx = &ml->cfgm;
	c.software = co_swmgr_line_check;
	c.software_ctx = &ml->swm;
	c.pdo_layout = co_pdo_scan_line_step;
	c.pdo_layout_ctx = &ml->scan;
	memset(ml->scan.cfg, 0, sizeof ml->scan.cfg);
	for (size_t i = 0; i < ml->lc.n_nodes; i++) {
		const mgr_ext_node *n = &ml->lc.nodes[i];
		ml->scan.cfg[n->id] = (co_pdo_scan_node){
			.scan = n->pdo_scan,
			.from_file = n->pdo_from_file,
			.scan_if_reconfigured = n->pdo_scan_if_reconfigured,
			.types = n->pdo_types,
			.n_types = n->n_pdo_types,
		};
	}
	co_pdo_scan_line_init(&ml->scan, node, line_pdo_layout(l), scan_done, ml);
	ml->scan.sdo_timeout_ms = c.sdo_timeout_ms;
	co_cfgmgr_line_init(&ml->cfgm, node, cfgm_done, ml);
	co_swmgr_line_init(&ml->swm, node, &src, swm_done, ml);
	ml->swm.sdo_timeout_ms = c.sdo_timeout_ms;
	ml->swm.progress = swm_progress;
	ml->swm.progress_ctx = ml;
	ml->l = l;
	ml->cfgm.sdo_timeout_ms = c.sdo_timeout_ms;
	for (size_t i = 0; i < ml->lc.n_nodes; i++) /* "store": 1010h after a download */
		ml->cfgm.store[ml->lc.nodes[i].id] = ml->lc.nodes[i].store;
	if ((rc = co_manager_create(&ml->mgr, node, &c)) < 0) {
		cogw_log(COGW_LOG_ERR, "line %s: manager: %s (the line needs sdo_clients >= 1)",
			 ml->lc.name, strerror(-rc));
		return rc;
	}
	for (size_t i = 0; i < ml->lc.n_nodes; i++) {
		const mgr_ext_node *n = &ml->lc.nodes[i];
		if (n->keep_op)
			(void)co_manager_set_keep_op(ml->mgr, n->id, true);
		(void)co_manager_set_target_state(ml->mgr, n->id, n->target_state);
	}
	return 0;
}

static void mgr_detach(void *ctx, line *l)
{
	struct mgr_line *ml = ctx;
	(void)l;
	ml->l = NULL; /* the line is stopping: nobody is answered any more */
	co_cfgmgr_line_cancel_all(&ml->cfgm, line_loop_now_us(l));
	co_swmgr_line_cancel_all(&ml->swm, line_loop_now_us(l));
	co_pdo_scan_line_cancel_all(&ml->scan, line_loop_now_us(l));
	co_manager_destroy(ml->mgr);
	ml->l = NULL;
	ml->mgr = NULL;
}

static void log_event(const struct mgr_line *ml, const co_event *ev)
{
	const co_ev_mgr *e = &ev->u.mgr;
	switch (ev->kind) {
	case CO_EV_MGR_STATE:
		cogw_log(COGW_LOG_INFO, "line %s: manager %s (flags %02x)", ml->lc.name,
			 co_mgr_state_to_string(e->state), e->flags);
		break;
	case CO_EV_MGR_BOOT:
		if (e->status && e->status != 'L')
			cogw_log(COGW_LOG_WARNING,
				 "line %s: boot of node %u failed at %s %04X:%02X: status %c (%s), "
				 "abort %08X (%s)",
				 ml->lc.name, e->node, co_mgr_step_to_string(e->step), e->index,
				 e->sub, e->status, co_mgr_status_to_string(e->status), e->abort,
				 e->abort ? sdo_abort_to_string(e->abort) : "none");
		else if (e->done)
			cogw_log(COGW_LOG_INFO, "line %s: node %u booted", ml->lc.name, e->node);
		break;
	case CO_EV_MGR_NODE:
		cogw_log(e->what == CO_MGR_NODE_OWN_ID || e->what == CO_MGR_NODE_DUPLICATE
				 ? COGW_LOG_ERR
				 : COGW_LOG_NOTICE,
			 "line %s: node %u: %s (%u)", ml->lc.name, e->node,
			 co_mgr_node_what_to_string(e->what), e->value);
		break;
	default:
		break;
	}
}

static void mgr_on_core_event(void *ctx, line *l, const co_event *ev)
{
	struct mgr_line *ml = ctx;
	uint16_t code;

	switch (ev->kind) {
	case CO_EV_MGR_STATE:
		code = MBX_EV_MGR_STATE;
		break;
	case CO_EV_MGR_BOOT:
		code = MBX_EV_MGR_BOOT;
		break;
	case CO_EV_MGR_NODE:
		code = MBX_EV_MGR_NODE;
		break;
	default:
		co_cfgmgr_line_on_event(&ml->cfgm, ev, ev->now_us);
		/* before the manager restarts a rebooted node's boot: its
		 * layout is invalid from its boot-up on */
		co_pdo_scan_line_on_event(&ml->scan, ev, ev->now_us);
		co_manager_on_event(ml->mgr, ev);
		return;
	}
	const co_ev_mgr *e = &ev->u.mgr;
	mbx_ev_mgr w = { .node = e->node,
			 .state = e->state,
			 .prev = e->prev,
			 .flags = e->flags,
			 .step = e->step,
			 .status = e->status,
			 .what = e->what,
			 .mandatory = e->mandatory,
			 .index = e->index,
			 .sub = e->sub,
			 .done = e->done,
			 .abort = e->abort,
			 .value = e->value,
			 .expected = e->expected };
	log_event(ml, ev);
	(void)mbx_server_publish(line_mbx(l), code, 0, &w, sizeof w);
}

static uint64_t mgr_poll(void *ctx, line *l, uint64_t now_us)
{
	struct mgr_line *ml = ctx;
	uint64_t a, b;
	(void)l;
	a = co_cfgmgr_line_tick(&ml->cfgm, now_us);
	b = co_manager_tick(ml->mgr, now_us);
	return a < b ? a : b;
}

static void copy_bits(mbx_mgr_bits *o, const co_mgr_bits *i)
{
	memcpy(o->w, i->w, sizeof o->w);
}

static int answer_status(struct mgr_line *ml, mbx_mgr_status *s)
{
	co_mgr_diag d;
	co_manager_get_diag(ml->mgr, &d);
	memset(s, 0, sizeof *s);
	s->state = d.state;
	s->flags = d.flags;
	s->first_error_node = d.first_error_node;
	s->first_error_status = d.first_error_status;
	s->first_error_code = d.first_error_code;
	s->nmt_ignored = d.nmt_ignored;
	s->unexpected = d.unexpected;
	s->duplicates = d.duplicates;
	s->errctrl_events = d.errctrl_events;
	s->keep_op_restarts = d.keep_op_restarts;
	s->network_boots = d.network_boots;
	copy_bits(&s->assigned, &d.assigned);
	copy_bits(&s->present, &d.present);
	copy_bits(&s->booted, &d.booted);
	copy_bits(&s->operational, &d.operational);
	copy_bits(&s->stopped, &d.stopped);
	copy_bits(&s->preop, &d.preop);
	copy_bits(&s->mismatch, &d.mismatch);
	copy_bits(&s->errctrl_lost, &d.errctrl_lost);
	copy_bits(&s->emcy_active, &d.emcy_active);
	s->node_changes = ml->node_changes;
	s->node_changes_refused = ml->node_changes_refused;
	return 0;
}

static void node_diag(struct mgr_line *ml, uint8_t node, mbx_mgr_node_diag *o)
{
	const co_mgr_node_diag *d = co_manager_node_diag(ml->mgr, node);
	memset(o, 0, sizeof *o);
	o->node = node;
	o->step = d->step;
	o->status = d->status;
	o->booted = d->booted;
	o->booting = d->booting;
	o->nmt_state = co_manager_node_nmt_state(ml->mgr, node);
	o->sub = d->sub;
	o->index = d->index;
	o->assignment = d->assignment;
	o->abort = d->abort;
	o->value = d->value;
	o->boot_count = d->boot_count;
	o->fail_count = d->fail_count;
	if (ml->l && node == co_node_id(line_node(ml->l))) {
		co_mgr_diag all;
		co_manager_get_diag(ml->mgr, &all);
		o->own_id_frames = all.own_id_frames;
	}
	o->boot_time_us = d->boot_time_us;
	o->n_emcy = d->emcy_count;
	for (unsigned i = 0; i < d->emcy_count; i++) {
		/* oldest first */
		unsigned k = (d->emcy_next + CO_MGR_EMCY_HISTORY - d->emcy_count + i) %
			     CO_MGR_EMCY_HISTORY;
		o->emcy[i].time_us = d->emcy[k].time_us;
		o->emcy[i].code = d->emcy[k].code;
		o->emcy[i].reg = d->emcy[k].reg;
		memcpy(o->emcy[i].msef, d->emcy[k].msef, sizeof o->emcy[i].msef);
	}
}

/*
 * MBX_CMD_MGR_PROGRAM: the software manager's sequence for one node with
 * the image of the request (validated by the mailbox: node 1..127, an
 * image of 1 byte .. max_transfer). Answered when the job ends; a refusal
 * at once: PARAM for the line's own node-ID, BUSY when the node's job
 * runs (its boot or another update) or MGR_PROGRAM_MAX updates run,
 * STATE when the manager holds the network stopped (no SDO there,
 * docs/config.md) or no SDO request can be queued.
 */
/* The refusal of a program update (0: none) and the free entry it takes. */
static int program_refusal(struct mgr_line *ml, line *l, const mbx_request *req,
			   const mbx_mgr_program_req *r, struct mgr_program **out)
{
	*out = NULL;
	if (r->node == co_node_id(line_node(l)) || !req->data_len || req->data_len > UINT32_MAX)
		return MBX_E_PARAM;
	if (co_manager_state(ml->mgr) == CO_MGR_STOPPED)
		return MBX_E_STATE;
	if (co_swmgr_running(&ml->swm.job[r->node - 1]) || program_of(ml, r->node))
		return MBX_E_BUSY;
	for (unsigned i = 0; i < MGR_PROGRAM_MAX && !*out; i++)
		if (!ml->prog[i].used)
			*out = &ml->prog[i];
	if (!*out || (!req->reply.slot && req->data_len > ml->copy_cap))
		return MBX_E_BUSY;
	return 0;
}

static void program_request(struct mgr_line *ml, line *l, const mbx_request *req, uint64_t now)
{
	mbx_server *srv = line_mbx(l);
	mbx_mgr_program_req r;
	struct mgr_program *p;
	int rc;

	memcpy(&r, req->payload, sizeof r);
	if ((rc = program_refusal(ml, l, req, &r, &p)) != 0) {
		(void)mbx_server_respond(srv, &req->reply, rc, 0, NULL, 0);
		return;
	}
	if (req->reply.slot) {
		p->image = req->data; /* chunked: valid until answered */
	} else {
		memcpy(p->copy, req->data, req->data_len);
		p->image = p->copy;
	}
	p->size = (uint32_t)req->data_len;
	p->node = r.node;
	p->reply = req->reply;
	p->used = true;
	const co_swmgr_source src = { .size = program_size, .read = program_read, .ctx = p };
	uint32_t timeout = ml->swm.sdo_timeout_ms;
	if (r.sdo_timeout_ms)
		ml->swm.sdo_timeout_ms = r.sdo_timeout_ms;
	cogw_log(COGW_LOG_NOTICE, "line %s: node %u: program update requested (%u bytes)",
		 ml->lc.name, r.node, (unsigned)p->size);
	rc = co_swmgr_line_program(&ml->swm, r.node, &src, r.expected, now);
	ml->swm.sdo_timeout_ms = timeout;
	if (rc < 0) {
		p->used = false;
		p->image = NULL;
		(void)mbx_server_respond(srv, &req->reply, mbx_status_of_errno(rc), 0, NULL, 0);
	}
}

/* ---- nodes at run time (docs/config.md "Nodes at run time") ------------------- */

/* A write through the OD's hooks, as an SDO write would be: the heartbeat
 * consumer loads 1016h:sub again, the manager follows 1F81h:n, the
 * configuration manager checks 1F22h:n. The defaults stay the file's (a
 * reset communication of the daemon's own node returns to them, as after
 * any SDO write). Returns 0 or the abort code. */
static uint32_t od_put(co_od *od, uint16_t index, uint8_t sub, const uint8_t *data, uint32_t len)
{
	co_od_entry *e = co_od_find(od, index, sub);
	co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL, .data = data, .size = len };

	return e ? co_od_write(e, data, len, &a) : SDO_AB_NO_OBJ;
}

static uint32_t od_put_u32(co_od *od, uint16_t index, uint8_t sub, uint32_t v)
{
	uint8_t b[4] = { (uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24) };
	return od_put(od, index, sub, b, sizeof b);
}

/* The manager's part of a refusal: its state, the node's place in the
 * list, a program download to it. */
static int node_list_refusal(struct mgr_line *ml, const co_od *od, const line_node_set *set)
{
	const mbx_mgr_node_set_req *r = &set->req;
	uint8_t st = co_manager_state(ml->mgr);
	uint32_t a = 0;
	bool listed;

	/* the network boot reads the objects step by step (their lock,
	 * core/manager_od.c); FATAL and slave mode boot nobody */
	if (st == CO_MGR_SLAVE || st == CO_MGR_RESETTING || st == CO_MGR_BOOTING ||
	    st == CO_MGR_FATAL)
		return -EAGAIN;
	(void)co_od_get_u32(od, 0x1F81, r->node, &a);
	listed = a & CO_MGR_1F81_SLAVE;
	/* an addition needs a node not listed, a change or removal a listed
	 * one; a reload makes the node what the file says either way */
	if (!set->as_file && listed != (r->op != MBX_NODE_ADD))
		return listed ? -EEXIST : -ENOENT;
	if (co_swmgr_running(&ml->swm.job[r->node - 1]) || program_of(ml, r->node))
		return -EBUSY; /* a program download must not be cut short */
	return 0;
}

/* Why a change cannot be applied now (0: it can): nothing is written then. */
static int node_refusal(struct mgr_line *ml, line *l, const line_node_set *set)
{
	const mbx_mgr_node_set_req *r = &set->req;
	const co_od *od = co_node_od(line_node(l));
	const co_od_entry *cdcf;
	int rc;

	if (r->node < 1 || r->node > 127 || r->node == co_node_id(line_node(l)))
		return -EINVAL;
	if ((rc = node_list_refusal(ml, od, set)) || r->op == MBX_NODE_REMOVE || !set->cdcf_len)
		return rc;
	if (co_cdcf_check(set->cdcf, set->cdcf_len, NULL, NULL))
		return -EINVAL;
	cdcf = co_od_find(od, CO_CFGMGR_IDX_CDCF, r->node);
	return !cdcf || set->cdcf_len > cdcf->max_size ? -E2BIG : 0;
}

/* The objects of node s->req.node in the order the boot reads them:
 * 1F81h:n is withdrawn first (a boot that runs stops, its jobs are
 * cancelled without a report) and written last (the node boots with
 * everything in place). s is what the node gets: all zero for a removal.
 * Refusals were ruled out by node_refusal; a write the OD still refuses is
 * logged (it would be a programming error). */
static void node_objects(struct mgr_line *ml, line *l, uint8_t id, const line_node_set *s,
			 uint64_t now)
{
	co_od *od = co_node_od(line_node(l));
	uint32_t ab = od_put_u32(od, 0x1F81, id, 0);

	(void)co_cfgmgr_cancel(&ml->cfgm.job[id - 1], now);
	co_pdo_scan_line_forget(&ml->scan, id, now);
	if (!ab && line_consumer_set(l, id, 0) < 0)
		ab = SDO_AB_GENERAL;
	for (unsigned k = 0; k < 5 && !ab; k++)
		ab = od_put_u32(od, (uint16_t)(0x1F84 + k), id, s->req.identity[k]);
	if (!ab && co_od_find(od, CO_CFGMGR_IDX_CDCF, id)) {
		ab = od_put(od, CO_CFGMGR_IDX_CDCF, id, s->cdcf, s->cdcf_len);
		if (!ab)
			ab = od_put_u32(od, CO_CFGMGR_IDX_DATE, id, s->req.date);
		if (!ab)
			ab = od_put_u32(od, CO_CFGMGR_IDX_TIME, id, s->req.time);
	}
	if (!ab && s->req.heartbeat_ms && line_consumer_set(l, id, s->req.heartbeat_ms) < 0)
		ab = SDO_AB_GENERAL;
	if (!ab && s->req.assignment)
		ab = od_put_u32(od, 0x1F81, id, s->req.assignment);
	if (ab)
		cogw_log(COGW_LOG_ERR, "line %s: node %u: its objects refused a change: %08X (%s)",
			 ml->lc.name, id, (unsigned)ab, sdo_abort_to_string(ab));
}

/* Add, change or remove one node on the line thread (the mailbox's
 * MGR_NODE_SET and a reload's line_request_node): 0 or a negative errno. */
static int node_set(struct mgr_line *ml, line *l, const line_node_set *set)
{
	static const char *const ops[] = { "?", "added", "changed", "removed" };
	static const line_node_set removed; /* what a removed node keeps */
	const mbx_mgr_node_set_req *r = &set->req;
	const line_node_set *s = r->op == MBX_NODE_REMOVE ? &removed : set;
	uint8_t id = r->node;
	int rc = node_refusal(ml, l, set);

	if (rc) {
		ml->node_changes_refused++;
		return rc;
	}
	ml->scan.cfg[id] = (co_pdo_scan_node){ .scan = s->req.pdo != 0,
					       .types = s->types,
					       .n_types = s->n_types };
	ml->cfgm.store[id] = s->req.flags & MBX_NODE_F_STORE;
	(void)co_manager_set_keep_op(ml->mgr, id, s->req.flags & MBX_NODE_F_KEEP_OP);
	(void)co_manager_set_target_state(
		ml->mgr, id, s->req.target_state ? s->req.target_state : CO_NMT_OPERATIONAL);
	node_objects(ml, l, id, s, line_loop_now_us(l));
	ml->node_changes++;
	cogw_log(COGW_LOG_NOTICE,
		 "line %s: node %u %s at run time (1F81h:%u = %08X, heartbeat %u ms, concise DCF "
		 "%u bytes)",
		 ml->lc.name, id, ops[r->op <= 3 ? r->op : 0], id, (unsigned)s->req.assignment,
		 s->req.heartbeat_ms, (unsigned)s->cdcf_len);
	line_node_changed(l, &(line_node_news){ .node = id,
						.removed = s == &removed,
						.pdo = s->req.pdo,
						.types = s->types,
						.n_types = s->n_types });
	return 0;
}

static int mgr_node_set(void *ctx, line *l, const line_node_set *set)
{
	return node_set(ctx, l, set);
}

/* MBX_CMD_MGR_NODE_SET: the mailbox validated the fixed part (node range,
 * operation, flags, state); the concise DCF is the request's data. */
static void node_command(struct mgr_line *ml, line *l, const mbx_request *req)
{
	line_node_set set = { .cdcf = req->data_len ? req->data : NULL,
			      .cdcf_len = (uint32_t)req->data_len };
	int rc;

	memcpy(&set.req, req->payload, sizeof set.req);
	if (req->data_len > UINT32_MAX)
		rc = -E2BIG;
	else
		rc = node_set(ml, l, &set);
	if (rc)
		cogw_log(COGW_LOG_WARNING, "line %s: node %u: change over the mailbox refused: %s",
			 ml->lc.name, set.req.node, strerror(-rc));
	(void)mbx_server_respond(line_mbx(l), &req->reply,
				 rc == -ENOENT ? MBX_E_NOT_FOUND : mbx_status_of_errno(rc), 0, NULL,
				 0);
}

static void mgr_on_command(void *ctx, line *l, const mbx_request *req)
{
	struct mgr_line *ml = ctx;
	mbx_server *srv = line_mbx(l);
	uint64_t now = line_loop_now_us(l);
	int rc = 0;

	switch (req->code) {
	case MBX_CMD_MGR_STATUS: {
		mbx_mgr_status s;
		answer_status(ml, &s);
		(void)mbx_server_respond(srv, &req->reply, 0, 0, &s, sizeof s);
		return;
	}
	case MBX_CMD_MGR_NODE_DIAG: {
		mbx_mgr_node_req r;
		mbx_mgr_node_diag d;
		memcpy(&r, req->payload, sizeof r);
		node_diag(ml, r.node, &d);
		(void)mbx_server_respond(srv, &req->reply, 0, 0, &d, sizeof d);
		return;
	}
	case MBX_CMD_MGR_BOOT: {
		mbx_mgr_node_req r;
		memcpy(&r, req->payload, sizeof r);
		rc = r.node ? co_manager_boot_node(ml->mgr, r.node, now)
			    : co_manager_boot_network(ml->mgr, now);
		break;
	}
	case MBX_CMD_MGR_START:
		rc = co_manager_start_network(ml->mgr, now);
		break;
	case MBX_CMD_MGR_REQUEST_NMT: {
		mbx_mgr_nmt_req r;
		memcpy(&r, req->payload, sizeof r);
		rc = co_manager_request_nmt(ml->mgr, r.node, r.cmd, now);
		break;
	}
	case MBX_CMD_MGR_RESET_COUNTERS:
		co_manager_reset_counters(ml->mgr);
		ml->node_changes = ml->node_changes_refused = 0;
		break;
	case MBX_CMD_MGR_PROGRAM:
		program_request(ml, l, req, now);
		return;
	case MBX_CMD_MGR_NODE_SET:
		node_command(ml, l, req);
		return;
	default:
		rc = -EINVAL;
		(void)mbx_server_respond(srv, &req->reply, MBX_E_UNKNOWN_CMD, 0, NULL, 0);
		return;
	}
	(void)mbx_server_respond(srv, &req->reply, mbx_status_of_errno(rc), 0, NULL, 0);
}

static bool mgr_nmt_master(void *ctx, line *l)
{
	struct mgr_line *ml = ctx;

	(void)l;
	return co_manager_state(ml->mgr) != CO_MGR_SLAVE;
}

/* A safety reaction of the line (lines/line_appwd.c) as the 1F82h request
 * of all nodes: the manager then holds the network in that state (a stop
 * or pre-operational is not undone by the boot of a late node; a reset
 * boots the network again) until it is asked to start it. */
static int mgr_nmt_all(void *ctx, line *l, uint8_t cs, uint64_t now_us)
{
	struct mgr_line *ml = ctx;
	uint8_t cmd;

	switch (cs) {
	case CO_NMT_CS_START:
		cmd = CO_MGR_REQ_START;
		break;
	case CO_NMT_CS_STOP:
		cmd = CO_MGR_REQ_STOP;
		break;
	case CO_NMT_CS_ENTER_PREOP:
		cmd = CO_MGR_REQ_PREOP;
		break;
	case CO_NMT_CS_RESET_COMM:
		cmd = CO_MGR_REQ_RESET_COMM;
		break;
	case CO_NMT_CS_RESET_NODE:
		cmd = CO_MGR_REQ_RESET_NODE;
		break;
	default:
		return -EINVAL;
	}
	if (!mgr_nmt_master(ctx, l))
		return -EPERM;
	return co_manager_request_nmt(ml->mgr, CO_MGR_ALL_NODES, cmd, now_us);
}

/* unknown_nodes "boot" (lines/line_scan.c): a node outside the
 * configuration whose identity a device file of the directory has. */
static int mgr_adopt_node(void *ctx, line *l, uint8_t node, const uint32_t ident[5])
{
	struct mgr_line *ml = ctx;
	const mgr_ext_device *d = mgr_adopt_match(ml->lc.devices, ml->lc.n_devices, ident);
	if (!d)
		return -ENOENT;
	int rc = mgr_adopt_boot(ml->mgr, line_node(l), node, d, ident, line_loop_now_us(l));
	if (rc < 0)
		cogw_log(COGW_LOG_ERR, "line %s: node %u matches %s but cannot be booted: %s",
			 ml->lc.name, node, d->file, strerror(-rc));
	else
		cogw_log(COGW_LOG_INFO, "line %s: node %u is booted as an optional slave with %s",
			 ml->lc.name, node, d->file);
	return rc == -ENOENT ? -EIO : rc;
}

static const line_ext_ops mgr_ops = {
	.name = "manager",
	.attach = mgr_attach,
	.detach = mgr_detach,
	.on_core_event = mgr_on_core_event,
	.cmd_first = MBX_CMD_MGR_STATUS,
	.cmd_last = MBX_CMD_MGR_NODE_SET,
	.on_command = mgr_on_command,
	.poll = mgr_poll,
	.adopt_node = mgr_adopt_node,
	.node_set = mgr_node_set,
	.nmt_all = mgr_nmt_all,
	.nmt_master = mgr_nmt_master,
};

void mgr_ext_destroy(mgr_ext *x)
{
	if (!x)
		return;
	for (unsigned i = 0; i < MGR_EXT_LINES_MAX; i++) {
		for (unsigned k = 0; k < MGR_PROGRAM_MAX; k++)
			free(x->lines[i].prog[k].copy);
		free(x->lines[i].devices);
	}
	free(x);
}

int mgr_ext_create(mgr_ext **out, const mgr_ext_params *p)
{
	mgr_ext *x;
	bool any = false;

	*out = NULL;
	if (!p || p->n_lines > MGR_EXT_LINES_MAX)
		return -EINVAL;
	for (unsigned i = 0; i < p->n_lines; i++)
		any = any || p->line[i].enabled;
	if (!any)
		return 0;
	x = calloc(1, sizeof *x);
	if (!x)
		return -ENOMEM;
	x->n_lines = p->n_lines;
	for (unsigned i = 0; i < p->n_lines; i++) {
		struct mgr_line *ml = &x->lines[i];
		ml->lc = p->line[i];
		ml->lc.devices = NULL;
		ml->lc.n_devices = 0;
		if (!ml->lc.enabled)
			continue;
		/* the table of device files is the extension's own (the files'
		 * data it points to outlives it) */
		if (p->line[i].n_devices) {
			size_t sz = p->line[i].n_devices * sizeof p->line[i].devices[0];
			if (!(ml->devices = malloc(sz))) {
				mgr_ext_destroy(x);
				return -ENOMEM;
			}
			memcpy(ml->devices, p->line[i].devices, sz);
			ml->lc.devices = ml->devices;
			ml->lc.n_devices = p->line[i].n_devices;
		}
		/* the largest image that arrives in one message (not chunked) */
		ml->copy_cap = p->msg_size > MBX_HDR_SIZE + sizeof(mbx_mgr_program_req)
				       ? p->msg_size - MBX_HDR_SIZE - sizeof(mbx_mgr_program_req)
				       : 0;
		for (unsigned k = 0; k < MGR_PROGRAM_MAX; k++) {
			ml->prog[k].copy = malloc(ml->copy_cap ? ml->copy_cap : 1);
			if (!ml->prog[k].copy) {
				mgr_ext_destroy(x);
				return -ENOMEM;
			}
		}
	}
	*out = x;
	return 0;
}

void mgr_ext_line(mgr_ext *x, unsigned line_no, line_ext *out)
{
	out->ops = NULL;
	out->ctx = NULL;
	out->wake_fd = -1;
	if (!x || line_no >= x->n_lines || !x->lines[line_no].lc.enabled)
		return;
	out->ops = &mgr_ops;
	out->ctx = &x->lines[line_no];
}
