/* SPDX-License-Identifier: MIT */
/*
 * lines/line_appwd.c - the safety side of the application on the mailbox
 * (docs/application.md, "The application watchdog and host ready"):
 *
 *   APP_WATCHDOG  a writer declares itself essential (core/appwd.h);
 *                 declaring again after a trip acknowledges it
 *   APP_KEEPALIVE arms (first) and renews its deadline
 *   APP_HOLD      holds the own node out of OPERATIONAL (the NMT veto,
 *                 core/nmt.h): a start is refused and deferred, CiA 301
 *                 leaves the node where it was; the release applies it
 *   HOST_READY    not ready: safe outputs, the network held by the NMT
 *                 master, the own node PRE-OPERATIONAL (its TPDOs stop),
 *                 requests for the line's nodes refused; ready resumes
 *   APP_STATUS    all of it, with the counters
 *
 * The deadlines are the line's own: line_appwd_poll() runs in every loop
 * iteration and gives the loop its next deadline, so a client that is
 * killed, stopped or silent trips by the line's timer alone. The
 * reactions use only what the line holds (the reaction set, the safe
 * values): nothing waits for a client.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <string.h>

#include "core/appwd.h"
#include "core/nmt.h"
#include "lines/log.h"

_Static_assert((unsigned)MBX_APPWD_R_EMCY == CO_APPWD_EMCY &&
		       (unsigned)MBX_APPWD_R_NMT_PREOP == CO_APPWD_NMT_PREOP &&
		       (unsigned)MBX_APPWD_R_NMT_STOP == CO_APPWD_NMT_STOP &&
		       (unsigned)MBX_APPWD_R_NMT_RESET_COMM == CO_APPWD_NMT_RESET_COMM &&
		       (unsigned)MBX_APPWD_R_NMT_RESET_NODE == CO_APPWD_NMT_RESET_NODE &&
		       (unsigned)MBX_APPWD_R_HB_STOP == CO_APPWD_HB_STOP &&
		       (unsigned)MBX_APPWD_R_SAFE_OUTPUTS == CO_APPWD_SAFE_OUTPUTS &&
		       MBX_APPWD_R_ALL == CO_APPWD_ALL && MBX_APPWD_MAX == CO_APPWD_MAX,
	       "the wire's reaction bits are the core's");

/* ---- the NMT master and the own node ------------------------------------ */

/* A safety reaction's NMT command to all nodes, through the extension that
 * is the line's NMT master (line_ext.h nmt_all). 0 or -EPERM (none). */
static int nmt_all(line *l, uint8_t cs)
{
	for (unsigned i = 0; i < l->ext_attached; i++) {
		const line_ext *x = &l->p.ext[i];
		if (x->ops && x->ops->nmt_all && x->ops->nmt_master &&
		    x->ops->nmt_master(x->ctx, l))
			return x->ops->nmt_all(x->ctx, l, cs, l->now_us);
	}
	return -EPERM;
}

static bool nmt_master(line *l)
{
	for (unsigned i = 0; i < l->ext_attached; i++) {
		const line_ext *x = &l->p.ext[i];
		if (x->ops && x->ops->nmt_master && x->ops->nmt_master(x->ctx, l))
			return true;
	}
	return false;
}

static uint8_t app_flags(const line *l)
{
	return (uint8_t)((l->appwd.start_deferred ? MBX_APPWD_NMT_DEFERRED : 0) |
			 (l->appwd.host_not_ready ? MBX_APPWD_NMT_HOST_NOT_READY : 0));
}

static mbx_appwd_nmt own_nmt(const line *l, uint8_t prev, uint8_t cs)
{
	return (mbx_appwd_nmt){ .state = co_nmt_get_state(l->node),
				.prev = prev,
				.cs = cs,
				.flags = app_flags(l),
				.holders = l->appwd.n_holders,
				.node = co_node_id(l->node) };
}

/* The veto on OPERATIONAL (core/nmt.h): refused while a client holds the
 * node or the host is not ready; the start is remembered for the release. */
static bool allow_operational(void *ctx, co_node *node, uint8_t from, uint8_t to)
{
	line *l = ctx;
	(void)node;
	(void)to;
	if (!l->appwd.n_holders && !l->appwd.host_not_ready)
		return true;
	if (!l->appwd.start_deferred)
		cogw_log(COGW_LOG_INFO, "line %s: start of our node deferred (%s)", l->name,
			 l->appwd.host_not_ready ? "host not ready" : "held by a client");
	l->appwd.start_deferred = true;
	l->appwd.starts_refused++;
	mbx_appwd_nmt e = own_nmt(l, from, CO_NMT_CS_START);
	e.flags |= MBX_APPWD_NMT_REFUSED;
	mbx_server_publish(l->mbx, MBX_EV_APP_NMT, 0, &e, sizeof e);
	return false;
}

/* Nothing holds the node any more: the start that was refused meanwhile. */
static void release(line *l)
{
	if (l->appwd.n_holders || l->appwd.host_not_ready || !l->appwd.start_deferred)
		return;
	l->appwd.start_deferred = false;
	if (co_nmt_get_state(l->node) != CO_NMT_OPERATIONAL)
		(void)co_nmt_local_cmd(l->node, CO_NMT_CS_START, l->now_us);
}

void line_appwd_on_nmt(line *l, const co_ev_nmt *ev)
{
	/* a later command than the deferred start decides (a stop, a reset) */
	if (ev->cs && ev->cs != CO_NMT_CS_START && !l->appwd.host_not_ready)
		l->appwd.start_deferred = false;
	mbx_appwd_nmt e = own_nmt(l, ev->prev, ev->cs);
	mbx_server_publish(l->mbx, MBX_EV_APP_NMT, 0, &e, sizeof e);
}

void line_appwd_attach(line *l)
{
	co_appwd_init(&l->appwd.wd);
	co_nmt_set_veto(l->node, allow_operational, l);
}

/* ---- the watchdog -------------------------------------------------------- */

static uint32_t unavailable(line *l, uint32_t set)
{
	uint32_t u = 0;
	if ((set & CO_APPWD_NMT_MASK) && !nmt_master(l))
		u |= set & CO_APPWD_NMT_MASK;
	if ((set & CO_APPWD_SAFE_OUTPUTS) && !l->p.n_safe_outputs)
		u |= CO_APPWD_SAFE_OUTPUTS;
	return u;
}

static void trip(line *l, const co_appwd_entry *e)
{
	uint32_t done = co_appwd_react(l->node, e->reactions, l->p.safe_outputs,
				       l->p.n_safe_outputs, &l->appwd.fx, l->now_us);
	uint8_t cs = co_appwd_nmt_cs(e->reactions);
	if (cs && nmt_all(l, cs) == 0)
		done |= e->reactions & CO_APPWD_NMT_MASK;
	uint64_t late = l->now_us - e->deadline_us;
	l->appwd.last.client = e->owner;
	l->appwd.last.pid = e->pid;
	l->appwd.last.done = done;
	l->appwd.last.late_us = late > UINT32_MAX ? UINT32_MAX : (uint32_t)late;
	l->appwd.last.at_us = l->now_us;
	mbx_ev_appwd ev = { .client = e->owner,
			    .pid = e->pid,
			    .interval_ms = e->interval_ms,
			    .reactions = e->reactions,
			    .done = done,
			    .late_us = l->appwd.last.late_us,
			    .deadline_us = e->deadline_us,
			    .trips = (uint32_t)l->appwd.wd.stats.trips,
			    .gone = e->gone };
	mbx_server_publish(l->mbx, MBX_EV_APP_WD_TIMEOUT, 0, &ev, sizeof ev);
	char what[128];
	mbx_appwd_reactions_format(done, what, sizeof what);
	cogw_log(COGW_LOG_WARNING,
		 "line %s: application watchdog: client %u (pid %u%s) missed its %u ms "
		 "keep-alive; %u us after the deadline: %s",
		 l->name, e->owner, e->pid, e->gone ? ", gone" : "", e->interval_ms,
		 l->appwd.last.late_us, what);
}

uint64_t line_appwd_poll(line *l)
{
	co_appwd_entry fired[CO_APPWD_MAX];
	size_t n = co_appwd_poll(&l->appwd.wd, l->now_us, fired, CO_APPWD_MAX);
	for (size_t i = 0; i < n; i++)
		trip(l, &fired[i]);
	return co_appwd_next_deadline(&l->appwd.wd);
}

/* No entry tripped any more: undo what can be undone (core/appwd.h). */
static void acknowledge(line *l)
{
	if (co_appwd_any_tripped(&l->appwd.wd) || (!l->appwd.fx.emcy && !l->appwd.fx.hb_stopped))
		return;
	co_appwd_acknowledge(l->node, &l->appwd.fx, l->now_us);
	cogw_log(COGW_LOG_INFO, "line %s: application watchdog acknowledged", l->name);
}

static void app_watchdog(line *l, const mbx_request *req)
{
	mbx_appwd_req r;
	memcpy(&r, req->payload, sizeof r);
	uint32_t set = r.reactions == MBX_APPWD_R_CONFIGURED ? l->p.app_reactions : r.reactions;
	if (r.interval_ms && !set) /* the configured set, and the line has none */
		return line_answer(l, &req->reply, MBX_E_UNSUPPORTED, 0, NULL, 0);
	int rc = co_appwd_declare(&l->appwd.wd, req->reply.client, req->pid, r.interval_ms, set);
	if (rc == -ENOENT)
		return line_answer(l, &req->reply, MBX_E_NOT_FOUND, 0, NULL, 0);
	if (rc < 0)
		return line_answer(l, &req->reply, mbx_status_of_errno(rc), 0, NULL, 0);
	acknowledge(l);
	if (!r.interval_ms) {
		cogw_log(COGW_LOG_INFO, "line %s: client %u (pid %u) is no longer essential",
			 l->name, req->reply.client, req->pid);
		return line_answer(l, &req->reply, 0, 0, NULL, 0);
	}
	mbx_appwd_resp resp = { .reactions = set, .unavailable = unavailable(l, set) };
	char what[128];
	mbx_appwd_reactions_format(set, what, sizeof what);
	cogw_log(COGW_LOG_INFO, "line %s: client %u (pid %u) essential: %u ms, %s", l->name,
		 req->reply.client, req->pid, r.interval_ms, what);
	line_answer(l, &req->reply, 0, 0, &resp, sizeof resp);
}

static void app_keepalive(line *l, const mbx_request *req)
{
	int rc = co_appwd_keepalive(&l->appwd.wd, req->reply.client, l->now_us);
	int status = rc == -ENOENT ? MBX_E_NOT_FOUND : rc == -ESTALE ? MBX_E_STATE : 0;
	line_answer(l, &req->reply, status, 0, NULL, 0);
}

/* ---- the hold on OPERATIONAL --------------------------------------------- */

static int holder_at(const line *l, uint32_t client)
{
	for (unsigned i = 0; i < l->appwd.n_holders; i++)
		if (l->appwd.holders[i] == client)
			return (int)i;
	return -1;
}

static void drop_holder(line *l, uint32_t client)
{
	int at = holder_at(l, client);
	if (at < 0)
		return;
	l->appwd.holders[at] = l->appwd.holders[--l->appwd.n_holders];
	release(l);
}

static void app_hold(line *l, const mbx_request *req)
{
	mbx_appwd_hold_req r;
	memcpy(&r, req->payload, sizeof r);
	uint32_t client = req->reply.client;
	if (!r.hold) {
		drop_holder(l, client);
	} else if (holder_at(l, client) < 0) {
		if (l->appwd.n_holders == LINE_APPWD_HOLDERS)
			return line_answer(l, &req->reply, MBX_E_BUSY, 0, NULL, 0);
		l->appwd.holders[l->appwd.n_holders++] = client;
	}
	mbx_appwd_nmt resp = own_nmt(l, 0, 0);
	line_answer(l, &req->reply, 0, 0, &resp, sizeof resp);
}

/* ---- host ready / not ready ---------------------------------------------- */

static uint8_t not_ready_cs(const line *l)
{
	return l->p.not_ready_cs ? l->p.not_ready_cs : CO_NMT_CS_STOP;
}

static uint32_t reaction_of_cs(uint8_t cs)
{
	return cs == CO_NMT_CS_ENTER_PREOP ? CO_APPWD_NMT_PREOP : CO_APPWD_NMT_STOP;
}

/* Outputs to their safe values while their TPDOs can still go, then the
 * network held, then the own node PRE-OPERATIONAL: its TPDOs stop and its
 * RPDOs are no longer applied (CiA 301 §7.3.2.2). */
static uint32_t go_not_ready(line *l)
{
	uint32_t done = 0;
	bool was_operational = co_nmt_get_state(l->node) == CO_NMT_OPERATIONAL;
	if (l->p.n_safe_outputs) {
		co_appwd_safe_outputs_apply(l->node, l->p.safe_outputs, l->p.n_safe_outputs,
					    l->now_us);
		done |= CO_APPWD_SAFE_OUTPUTS;
	}
	l->appwd.host_not_ready = true;
	l->appwd.not_ready_nmt = nmt_all(l, not_ready_cs(l)) == 0;
	if (l->appwd.not_ready_nmt)
		done |= reaction_of_cs(not_ready_cs(l));
	if (was_operational) {
		(void)co_nmt_local_cmd(l->node, CO_NMT_CS_ENTER_PREOP, l->now_us);
		l->appwd.start_deferred = true;
	}
	l->appwd.not_ready_episodes++;
	return done;
}

static void go_ready(line *l)
{
	l->appwd.host_not_ready = false;
	if (l->appwd.not_ready_nmt)
		(void)nmt_all(l, CO_NMT_CS_START);
	l->appwd.not_ready_nmt = false;
	release(l);
}

static void host_ready(line *l, const mbx_request *req)
{
	mbx_host_ready_req r;
	memcpy(&r, req->payload, sizeof r);
	if ((bool)r.ready != l->appwd.host_not_ready) /* no change */
		return line_answer(l, &req->reply, 0, 0, NULL, 0);
	mbx_ev_host ev = { .ready = r.ready, .client = req->reply.client };
	if (r.ready)
		go_ready(l);
	else
		ev.done = go_not_ready(l);
	char what[128];
	mbx_appwd_reactions_format(ev.done, what, sizeof what);
	cogw_log(r.ready ? COGW_LOG_INFO : COGW_LOG_WARNING, "line %s: host %s (client %u)%s%s",
		 l->name, r.ready ? "ready" : "not ready", req->reply.client, r.ready ? "" : ": ",
		 r.ready ? "" : what);
	mbx_server_publish(l->mbx, MBX_EV_HOST_STATE, 0, &ev, sizeof ev);
	line_answer(l, &req->reply, 0, 0, NULL, 0);
}

static bool is_safe_output(const line *l, uint16_t index, uint8_t sub)
{
	for (unsigned i = 0; i < l->p.n_safe_outputs; i++)
		if (l->p.safe_outputs[i].index == index && l->p.safe_outputs[i].sub == sub)
			return true;
	return false;
}

/* What a request names: an object of the own dictionary, or a node. */
static bool refused_sdo(const line *l, const mbx_request *req)
{
	mbx_sdo_req r;
	memcpy(&r, req->payload, sizeof r);
	if (r.node != co_node_id(l->node))
		return true;
	return req->code == MBX_CMD_SDO_DOWNLOAD && is_safe_output(l, r.index, r.sub);
}

static bool refused_gw_sdo(const line *l, const mbx_request *req)
{
	mbx_gw_sdo_req r;
	memcpy(&r, req->payload, sizeof r);
	return r.net == l->p.network_id && r.sdo.node != co_node_id(l->node);
}

bool line_appwd_refuses(const line *l, const mbx_request *req)
{
	if (!l->appwd.host_not_ready)
		return false;
	switch (req->code) {
	case MBX_CMD_SDO_UPLOAD:
	case MBX_CMD_SDO_DOWNLOAD:
		return refused_sdo(l, req);
	case MBX_CMD_GW_SDO_UPLOAD:
	case MBX_CMD_GW_SDO_DOWNLOAD:
		return refused_gw_sdo(l, req);
	case MBX_CMD_NMT: {
		mbx_nmt_req n;
		memcpy(&n, req->payload, sizeof n);
		return n.node != co_node_id(l->node);
	}
	case MBX_CMD_OD_WRITE:
	case MBX_CMD_PDO_WRITE: {
		mbx_obj_req o;
		memcpy(&o, req->payload, sizeof o);
		return is_safe_output(l, o.index, o.sub);
	}
	case MBX_CMD_EMCY_SEND: /* the own node's, not a request to a node */
		return false;
	default:
		return line_cmd_needs_bus(req->code);
	}
}

/* ---- status -------------------------------------------------------------- */

static void app_status(line *l, const mbx_request *req)
{
	uint8_t buf[sizeof(mbx_appwd_status) + CO_APPWD_MAX * sizeof(mbx_appwd_entry)];
	const co_appwd_stats *s = &l->appwd.wd.stats;
	mbx_appwd_status st = { .host_ready = !l->appwd.host_not_ready,
				.own_state = co_nmt_get_state(l->node),
				.holders = l->appwd.n_holders,
				.flags = app_flags(l),
				.configured = l->p.app_reactions,
				.safe_outputs = l->p.n_safe_outputs,
				.nmt_master = nmt_master(l),
				.not_ready_action = not_ready_cs(l),
				.declared = s->declared,
				.keepalives = s->keepalives,
				.refused = s->refused,
				.trips = s->trips,
				.late_keepalives = s->late_keepalives,
				.not_ready_episodes = l->appwd.not_ready_episodes,
				.starts_refused = l->appwd.starts_refused,
				.last_client = l->appwd.last.client,
				.last_pid = l->appwd.last.pid,
				.last_done = l->appwd.last.done,
				.last_late_us = l->appwd.last.late_us };
	if (l->appwd.last.at_us)
		st.last_age_ms = (l->now_us - l->appwd.last.at_us) / 1000u;
	for (unsigned i = 0; i < CO_APPWD_MAX; i++) {
		const co_appwd_entry *e = &l->appwd.wd.e[i];
		if (e->state == CO_APPWD_FREE)
			continue;
		mbx_appwd_entry w = { .client = e->owner,
				      .pid = e->pid,
				      .interval_ms = e->interval_ms,
				      .reactions = e->reactions,
				      .state = e->state,
				      .gone = e->gone,
				      .keepalives = e->keepalives };
		if (e->state == CO_APPWD_ARMED && e->deadline_us > l->now_us)
			w.left_ms = (uint32_t)((e->deadline_us - l->now_us) / 1000u);
		memcpy(buf + sizeof st + st.n++ * sizeof w, &w, sizeof w);
	}
	memcpy(buf, &st, sizeof st);
	line_answer(l, &req->reply, 0, 0, buf, sizeof st + st.n * sizeof(mbx_appwd_entry));
}

void line_appwd_command(line *l, const mbx_request *req)
{
	switch (req->code) {
	case MBX_CMD_APP_WATCHDOG:
		return app_watchdog(l, req);
	case MBX_CMD_APP_KEEPALIVE:
		return app_keepalive(l, req);
	case MBX_CMD_APP_HOLD:
		return app_hold(l, req);
	case MBX_CMD_HOST_READY:
		return host_ready(l, req);
	default:
		return app_status(l, req);
	}
}

void line_appwd_client_gone(line *l, uint32_t client)
{
	co_appwd_owner_gone(&l->appwd.wd, client);
	drop_holder(l, client);
}
