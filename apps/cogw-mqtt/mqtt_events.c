/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-mqtt/mqtt_events.c - what the bridge publishes on its own
 * (docs/mqtt.md "Topics"): the mailbox events of every line turned into
 * JSON on per-network, per-node topics, the node table, boot status and
 * manager state as retained state (asked of the daemon at every
 * subscription, republished on every connect to the broker), an EMCY
 * history per node, and the daemon's and the bridge's counters on a slow
 * period.
 */
#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "apps/cogw-mqtt/bridge.h"
#include "apps/cogw-mqtt/mqtt_watch.h"
#include "core/emcy.h"
#include "core/manager.h"
#include "core/nmt.h"

#define TOPIC_MAX 512

static node_state *node_of(bridge *b, unsigned line, uint8_t node)
{
	return &b->nodes[line * 128u + (node & 0x7Fu)];
}

static const char *nmt_text(uint8_t s)
{
	return s == 0xFF ? "unknown" : co_nmt_state_to_string(s);
}

static const char *hb_text(uint8_t hb)
{
	static const char *const names[] = { "not monitored", "active", "lost", "waiting" };

	return hb < 4 ? names[hb] : "unknown";
}

static void node_topic(const bridge *b, unsigned line, uint8_t node, const char *leaf, char *t,
		       size_t n)
{
	snprintf(t, n, "%s/%s/net/%u/node/%u/%s", b->cfg.topic_prefix, b->cfg.gateway,
		 b->daemon.lines[line].network_id, node, leaf);
}

static void net_topic(const bridge *b, unsigned line, const char *leaf, char *t, size_t n)
{
	snprintf(t, n, "%s/%s/net/%u/%s", b->cfg.topic_prefix, b->cfg.gateway,
		 b->daemon.lines[line].network_id, leaf);
}

/* Every payload starts with time, gateway, net (and node). */
static cJSON *head(const bridge *b, unsigned line, int node)
{
	cJSON *o = cJSON_CreateObject();
	char t[40];

	bridge_time_text(t, sizeof t);
	cJSON_AddStringToObject(o, "time", t);
	cJSON_AddStringToObject(o, "gateway", b->cfg.gateway);
	if (line < b->daemon.n_lines)
		cJSON_AddNumberToObject(o, "net", b->daemon.lines[line].network_id);
	if (node >= 0)
		cJSON_AddNumberToObject(o, "node", node);
	return o;
}

static void hex_text(uint32_t v, unsigned digits, char *buf, size_t n)
{
	snprintf(buf, n, "0x%0*X", (int)digits, v);
}

static void add_hex(cJSON *o, const char *key, uint32_t v, unsigned digits)
{
	char s[16];

	hex_text(v, digits, s, sizeof s);
	cJSON_AddStringToObject(o, key, s);
}

static void publish_nmt(bridge *b, unsigned line, uint8_t node, uint8_t state, int prev)
{
	char t[TOPIC_MAX];
	cJSON *o = head(b, line, node);

	cJSON_AddStringToObject(o, "state", nmt_text(state));
	if (prev >= 0)
		cJSON_AddStringToObject(o, "prev", nmt_text((uint8_t)prev));
	node_topic(b, line, node, "nmt", t, sizeof t);
	link_publish_json(b, t, o, true, NULL);
}

static void publish_heartbeat(bridge *b, unsigned line, uint8_t node, const char *event)
{
	char t[TOPIC_MAX];
	cJSON *o = head(b, line, node);
	node_state *ns = node_of(b, line, node);

	cJSON_AddStringToObject(o, "state", hb_text(ns->hb));
	if (event)
		cJSON_AddStringToObject(o, "event", event);
	node_topic(b, line, node, "heartbeat", t, sizeof t);
	link_publish_json(b, t, o, true, NULL);
}

static cJSON *emcy_json(uint16_t code, uint8_t reg, const uint8_t msef[5])
{
	cJSON *o = cJSON_CreateObject();
	char s[16];

	add_hex(o, "code", code, 4);
	cJSON_AddStringToObject(o, "text", co_emcy_code_to_string(code));
	add_hex(o, "register", reg, 2);
	snprintf(s, sizeof s, "%02X%02X%02X%02X%02X", msef[0], msef[1], msef[2], msef[3], msef[4]);
	cJSON_AddStringToObject(o, "msef", s);
	return o;
}

static void publish_emcy_history(bridge *b, unsigned line, uint8_t node)
{
	node_state *ns = node_of(b, line, node);
	cJSON *o = head(b, line, node), *arr = cJSON_AddArrayToObject(o, "history");
	char t[TOPIC_MAX];

	/* oldest first */
	for (unsigned i = 0; i < ns->n_emcy; i++) {
		unsigned k = (ns->emcy_head + 16u - ns->n_emcy + i) % 16u;
		cJSON *e = emcy_json(ns->emcy[k].code, ns->emcy[k].reg, ns->emcy[k].msef);
		char when[40];

		bridge_time_of(ns->emcy[k].time_ms, when, sizeof when);
		cJSON_AddStringToObject(e, "time", when);
		cJSON_AddItemToArray(arr, e);
	}
	node_topic(b, line, node, "emcy/history", t, sizeof t);
	link_publish_json(b, t, o, true, NULL);
}

static void on_emcy(bridge *b, unsigned line, const mbx_ev_emcy *e)
{
	node_state *ns = node_of(b, line, e->node);
	cJSON *o = head(b, line, e->node), *body = emcy_json(e->code, e->reg, e->msef);
	char t[TOPIC_MAX];

	for (cJSON *c = body->child; c; c = c->next)
		cJSON_AddItemToObject(o, c->string, cJSON_Duplicate(c, 1));
	cJSON_Delete(body);
	node_topic(b, line, e->node, "emcy", t, sizeof t);
	link_publish_json(b, t, o, false, NULL);
	if (!b->cfg.emcy_history)
		return;
	ns->emcy[ns->emcy_head].time_ms = bridge_wall_ms();
	ns->emcy[ns->emcy_head].code = e->code;
	ns->emcy[ns->emcy_head].reg = e->reg;
	memcpy(ns->emcy[ns->emcy_head].msef, e->msef, 5);
	ns->emcy_head = (ns->emcy_head + 1u) % 16u;
	if (ns->n_emcy < b->cfg.emcy_history)
		ns->n_emcy++;
	publish_emcy_history(b, line, e->node);
}

/* One boot step (CiA 302-2 boot process): retained, so that the topic
 * holds the node's boot status once the boot ended. */
static void on_mgr_boot(bridge *b, unsigned line, const mbx_ev_mgr *e)
{
	node_state *ns = node_of(b, line, e->node);
	cJSON *o = head(b, line, e->node);
	char t[TOPIC_MAX], st[2] = { e->status, 0 };

	cJSON_AddStringToObject(o, "step", co_mgr_step_to_string(e->step));
	cJSON_AddBoolToObject(o, "ok", !e->status || e->status == 'L');
	cJSON_AddBoolToObject(o, "done", e->done);
	cJSON_AddStringToObject(o, "status", st);
	if (e->status)
		cJSON_AddStringToObject(o, "status_text", co_mgr_status_to_string(e->status));
	add_hex(o, "index", e->index, 4);
	cJSON_AddNumberToObject(o, "sub", e->sub);
	add_hex(o, "abort", e->abort, 8);
	cJSON_AddNumberToObject(o, "value", e->value);
	cJSON_AddNumberToObject(o, "expected", e->expected);
	cJSON_AddBoolToObject(o, "mandatory", e->mandatory);
	free(ns->boot_json);
	ns->boot_json = cJSON_PrintUnformatted(o);
	node_topic(b, line, e->node, "boot", t, sizeof t);
	link_publish_json(b, t, o, true, NULL);
}

/* The boot status of a node the manager booted before the bridge was
 * there (MGR_NODE_DIAG): the same topic, from the node's last boot. */
static void on_node_diag(bridge *b, unsigned line, const cogw_msg *m)
{
	mbx_mgr_node_diag d;
	cJSON *o;
	char t[TOPIC_MAX], st[2];

	if (m->len < offsetof(mbx_mgr_node_diag, emcy))
		return;
	memset(&d, 0, sizeof d);
	memcpy(&d, m->data, m->len < sizeof d ? m->len : sizeof d);
	node_state *ns = node_of(b, line, d.node);

	/* a boot event came meanwhile, or the manager never tried this node */
	if (ns->boot_json || d.node < 1 || d.node > 127 || (!d.booted && !d.status && !d.booting))
		return;
	o = head(b, line, d.node);
	st[0] = d.status;
	st[1] = 0;
	cJSON_AddStringToObject(o, "step", co_mgr_step_to_string(d.step));
	cJSON_AddBoolToObject(o, "ok", !d.status || d.status == 'L');
	cJSON_AddBoolToObject(o, "done", d.booted);
	cJSON_AddStringToObject(o, "status", st);
	if (d.status)
		cJSON_AddStringToObject(o, "status_text", co_mgr_status_to_string(d.status));
	add_hex(o, "index", d.index, 4);
	cJSON_AddNumberToObject(o, "sub", d.sub);
	add_hex(o, "abort", d.abort, 8);
	cJSON_AddNumberToObject(o, "value", d.value);
	cJSON_AddNumberToObject(o, "boot_count", d.boot_count);
	cJSON_AddNumberToObject(o, "fail_count", d.fail_count);
	cJSON_AddNumberToObject(o, "boot_time_ms", (double)(d.boot_time_us / 1000u));
	ns->boot_json = cJSON_PrintUnformatted(o);
	node_topic(b, line, d.node, "boot", t, sizeof t);
	link_publish_json(b, t, o, true, NULL);
}

/* The line's manager state, retained; `prev` only on a change (-1: the
 * state as asked for or republished). */
static void publish_manager(bridge *b, unsigned line, uint8_t state, int prev, uint8_t flags)
{
	cJSON *o = head(b, line, -1);
	char t[TOPIC_MAX];

	cJSON_AddStringToObject(o, "state", co_mgr_state_to_string(state));
	if (prev >= 0)
		cJSON_AddStringToObject(o, "prev", co_mgr_state_to_string((uint8_t)prev));
	cJSON_AddNumberToObject(o, "flags", flags);
	net_topic(b, line, "manager", t, sizeof t);
	link_publish_json(b, t, o, true, NULL);
}

static void on_mgr_state(bridge *b, unsigned line, const mbx_ev_mgr *e)
{
	manager_state *ms = &b->managers[line];

	*ms = (manager_state){ .known = true, .state = e->state, .flags = e->flags };
	publish_manager(b, line, e->state, e->prev, e->flags);
}

/* The manager's present state (MGR_STATUS): a manager that changed state
 * before the bridge subscribed, or whose change was lost, sends no event
 * the bridge could have seen; published when it differs from what the
 * bridge knew. */
static void on_mgr_status(bridge *b, unsigned line, const cogw_msg *m)
{
	manager_state *ms = &b->managers[line];
	mbx_mgr_status s;

	if (m->len < offsetof(mbx_mgr_status, first_error_node))
		return;
	memcpy(&s, m->data, offsetof(mbx_mgr_status, first_error_node));
	if (ms->known && ms->state == s.state && ms->flags == s.flags)
		return;
	int prev = ms->known ? ms->state : -1;

	*ms = (manager_state){ .known = true, .state = s.state, .flags = s.flags };
	if (b->cfg.pub_manager)
		publish_manager(b, line, s.state, prev, s.flags);
}

static void on_mgr_node(bridge *b, unsigned line, const mbx_ev_mgr *e)
{
	cJSON *o = head(b, line, e->node);
	char t[TOPIC_MAX];

	cJSON_AddStringToObject(o, "event", co_mgr_node_what_to_string(e->what));
	cJSON_AddNumberToObject(o, "value", e->value);
	node_topic(b, line, e->node, "manager", t, sizeof t);
	link_publish_json(b, t, o, false, NULL);
}

/* A bus health fault, retained per fault, so a dashboard that connects
 * later sees which faults run now. */
static void publish_fault(bridge *b, unsigned line, const mbx_ev_comm_fault *e)
{
	cJSON *o = head(b, line, -1);
	char t[TOPIC_MAX], leaf[40];

	cJSON_AddStringToObject(o, "fault", mbx_fault_to_string(e->fault));
	cJSON_AddBoolToObject(o, "active", e->active);
	cJSON_AddStringToObject(o, "can_state", mbx_can_state_to_string(e->can_state));
	cJSON_AddNumberToObject(o, "episodes", e->episodes);
	cJSON_AddNumberToObject(o, "occurrences", e->occurrences);
	snprintf(leaf, sizeof leaf, "health/%s", mbx_fault_to_string(e->fault));
	net_topic(b, line, leaf, t, sizeof t);
	link_publish_json(b, t, o, true, NULL);
}

/* An essential client missed its keep-alive and the line ran its
 * reactions (docs/application.md): retained, the line's last trip. */
static void on_app_watchdog(bridge *b, unsigned line, const mbx_ev_appwd *e)
{
	cJSON *o = head(b, line, -1);
	char t[TOPIC_MAX], set[160];

	cJSON_AddNumberToObject(o, "client", e->client);
	cJSON_AddNumberToObject(o, "pid", e->pid);
	cJSON_AddBoolToObject(o, "client_gone", e->gone);
	cJSON_AddNumberToObject(o, "interval_ms", e->interval_ms);
	mbx_appwd_reactions_format(e->reactions, set, sizeof set);
	cJSON_AddStringToObject(o, "reactions", set);
	mbx_appwd_reactions_format(e->done, set, sizeof set);
	cJSON_AddStringToObject(o, "done", set);
	cJSON_AddNumberToObject(o, "late_us", e->late_us);
	cJSON_AddNumberToObject(o, "trips", e->trips);
	net_topic(b, line, "app/watchdog", t, sizeof t);
	link_publish_json(b, t, o, true, NULL);
}

static void on_host_state(bridge *b, unsigned line, const mbx_ev_host *e)
{
	cJSON *o = head(b, line, -1);
	char t[TOPIC_MAX], set[160];

	cJSON_AddBoolToObject(o, "ready", e->ready);
	cJSON_AddNumberToObject(o, "client", e->client);
	mbx_appwd_reactions_format(e->done, set, sizeof set);
	cJSON_AddStringToObject(o, "done", set);
	net_topic(b, line, "app/host", t, sizeof t);
	link_publish_json(b, t, o, true, NULL);
}

static void on_app_event(bridge *b, unsigned line, const cogw_msg *m)
{
	if (m->code == MBX_EV_APP_WD_TIMEOUT) {
		mbx_ev_appwd e;

		memcpy(&e, m->data, sizeof e);
		on_app_watchdog(b, line, &e);
	} else {
		mbx_ev_host e;

		memcpy(&e, m->data, sizeof e);
		on_host_state(b, line, &e);
	}
}

/* An episode began or ended. */
static void on_comm_fault(bridge *b, unsigned line, const mbx_ev_comm_fault *e)
{
	b->faults[line][e->fault] = (fault_state){ .known = true, .last = *e };
	publish_fault(b, line, e);
}

/* The line's present bus health (LINE_HEALTH), asked at every birth and
 * period: every fault is published the first time (a retained "active"
 * of an earlier run is replaced), later when an episode began or ended
 * that no event brought (lost with an overflowed queue, or before the
 * bridge subscribed). */
static void on_line_health(bridge *b, unsigned line, const cogw_msg *m)
{
	mbx_line_health h;

	if (m->len < sizeof h)
		return;
	memcpy(&h, m->data, sizeof h);
	for (unsigned i = 0; i < MBX_FAULT_COUNT && i < h.n_faults; i++) {
		fault_state *fs = &b->faults[line][i];
		mbx_ev_comm_fault e = { .fault = (uint8_t)i,
					.active = h.fault[i].active,
					.info = h.fault[i].info,
					.can_state = h.can_state,
					.episodes = h.fault[i].episodes,
					.occurrences = h.fault[i].occurrences };

		if (fs->known && fs->last.active == e.active && fs->last.episodes == e.episodes)
			continue;
		*fs = (fault_state){ .known = true, .last = e };
		publish_fault(b, line, &e);
	}
}

/* A node outside the line's configuration was heard (once per node and
 * daemon run), with its identity and what the line's policy did. */
static void on_unknown_node(bridge *b, unsigned line, const mbx_ev_unknown_node *e)
{
	const mbx_node_ident *id = &e->ident;
	cJSON *o = head(b, line, id->node);
	char t[TOPIC_MAX];

	cJSON_AddStringToObject(o, "source", mbx_ident_source_to_string(id->source));
	cJSON_AddBoolToObject(o, "identity", id->flags & MBX_IDENT_IDENTITY);
	cJSON_AddNumberToObject(o, "device_type", id->device_type);
	cJSON_AddNumberToObject(o, "vendor_id", id->vendor_id);
	cJSON_AddNumberToObject(o, "product_code", id->product_code);
	cJSON_AddNumberToObject(o, "revision", id->revision);
	cJSON_AddNumberToObject(o, "serial", id->serial);
	cJSON_AddStringToObject(o, "policy", mbx_unknown_policy_to_string(e->policy));
	cJSON_AddStringToObject(o, "action", mbx_unknown_action_to_string(e->action));
	node_topic(b, line, id->node, "unknown", t, sizeof t);
	link_publish_json(b, t, o, false, NULL);
}

static void on_node_event(bridge *b, unsigned line, uint16_t code, const mbx_ev_node *e)
{
	node_state *ns = node_of(b, line, e->node);
	char t[TOPIC_MAX];

	ns->known = true;
	switch (code) {
	case MBX_EV_NMT_STATE:
		ns->nmt = e->state;
		if (b->cfg.pub_nmt)
			publish_nmt(b, line, e->node, e->state, e->prev);
		break;
	case MBX_EV_BOOTUP:
		ns->nmt = 0x7F; /* a boot-up is followed by PRE-OPERATIONAL (CiA 301 §7.3.2.2) */
		if (b->cfg.pub_nmt) {
			cJSON *o = head(b, line, e->node);

			node_topic(b, line, e->node, "bootup", t, sizeof t);
			link_publish_json(b, t, o, false, NULL);
		}
		break;
	case MBX_EV_HB_STARTED: {
		bool was_lost = ns->hb == 2;

		ns->hb = 1;
		if (b->cfg.pub_heartbeat)
			publish_heartbeat(b, line, e->node, was_lost ? "resumed" : "started");
		break;
	}
	case MBX_EV_HB_LOST:
		ns->hb = 2;
		if (b->cfg.pub_heartbeat)
			publish_heartbeat(b, line, e->node, "lost");
		break;
	default:
		break;
	}
}

/* The manager's events: a node's boot step, the manager's state, a node's. */
static void on_mgr_event(bridge *b, unsigned line, const cogw_msg *m)
{
	mbx_ev_mgr e;

	memcpy(&e, m->data, sizeof e);
	if (m->code == MBX_EV_MGR_BOOT && b->cfg.pub_boot && e.node >= 1 && e.node <= 127)
		on_mgr_boot(b, line, &e);
	else if (m->code == MBX_EV_MGR_STATE && b->cfg.pub_manager)
		on_mgr_state(b, line, &e);
	else if (m->code == MBX_EV_MGR_NODE && b->cfg.pub_manager && e.node <= 127)
		on_mgr_node(b, line, &e);
}

void events_on_event(bridge *b, const cogw_msg *m)
{
	unsigned line = m->line;

	b->st.events++;
	if (m->dropped)
		b->st.events_lost += m->dropped;
	if (line >= b->daemon.n_lines)
		return;
	switch (m->code) {
	case MBX_EV_NMT_STATE:
	case MBX_EV_BOOTUP:
	case MBX_EV_HB_STARTED:
	case MBX_EV_HB_LOST: {
		mbx_ev_node e;

		memcpy(&e, m->data, sizeof e);
		if (e.node >= 1 && e.node <= 127)
			on_node_event(b, line, m->code, &e);
		break;
	}
	case MBX_EV_EMCY: {
		mbx_ev_emcy e;

		memcpy(&e, m->data, sizeof e);
		if (b->cfg.pub_emcy && e.node >= 1 && e.node <= 127)
			on_emcy(b, line, &e);
		break;
	}
	case MBX_EV_DEV_VALUE:
		mqtt_watch_on_value(b, m);
		break;
	case MBX_EV_COMM_FAULT: {
		mbx_ev_comm_fault e;

		memcpy(&e, m->data, sizeof e);
		if (b->cfg.pub_manager && e.fault < MBX_FAULT_COUNT)
			on_comm_fault(b, line, &e);
		break;
	}
	case MBX_EV_MGR_BOOT:
	case MBX_EV_MGR_STATE:
	case MBX_EV_MGR_NODE:
		on_mgr_event(b, line, m);
		break;
	case MBX_EV_APP_WD_TIMEOUT:
	case MBX_EV_HOST_STATE:
		on_app_event(b, line, m);
		break;
	case MBX_EV_UNKNOWN_NODE: {
		mbx_ev_unknown_node e;

		memcpy(&e, m->data, sizeof e);
		if (b->cfg.pub_manager && e.ident.node >= 1 && e.ident.node <= 127)
			on_unknown_node(b, line, &e);
		break;
	}
	default:
		break;
	}
}

/* ---- the node table, counters: the bridge's own mailbox requests -------- */

static void on_node_table(bridge *b, unsigned line, const cogw_msg *m)
{
	size_t n = m->len / sizeof(mbx_node_entry);

	for (size_t i = 0; i < n; i++) {
		mbx_node_entry e;

		memcpy(&e, m->data + i * sizeof e, sizeof e);
		if (e.node < 1 || e.node > 127)
			continue;
		node_state *ns = node_of(b, line, e.node);
		bool changed = !ns->known || ns->nmt != e.nmt_state;
		uint8_t hb = e.hb == 3 ? 0 : e.hb;

		if (!ns->boot_json && b->cfg.pub_boot && b->daemon.lines[line].manager.enabled) {
			mbx_mgr_node_req q = { .node = e.node };

			bridge_send_internal(b, line, MBX_CMD_MGR_NODE_DIAG, &q, sizeof q);
		}
		ns->known = true;
		ns->nmt = e.nmt_state;
		if (changed && b->cfg.pub_nmt)
			publish_nmt(b, line, e.node, e.nmt_state, -1);
		if (hb != ns->hb) {
			ns->hb = hb;
			if (b->cfg.pub_heartbeat && hb)
				publish_heartbeat(b, line, e.node, NULL);
		}
	}
}

#define ADD_U64(o, s, f) cJSON_AddNumberToObject(o, #f, (double)(s).f)

/* The mailbox server answers MBX_STATS itself, at once, and libcogw has
 * no asynchronous form for such commands: a short blocking call (the
 * daemon gone answers NO_DAEMON at once). */
static void publish_mbx_stats(bridge *b, unsigned line)
{
	mbx_stats_wire s;
	cJSON *o, *c;
	char t[TOPIC_MAX];
	int rc = cogw_mbx_stats(b->h, line, &s, 500);

	if (rc) {
		b->st.mbx_errors++;
		return;
	}
	o = head(b, line, -1);
	c = cJSON_AddObjectToObject(o, "mailbox");
	ADD_U64(c, s, commands_ok);
	ADD_U64(c, s, malformed);
	ADD_U64(c, s, access_denied);
	ADD_U64(c, s, events_sent);
	ADD_U64(c, s, responses_sent);
	ADD_U64(c, s, dropped);
	ADD_U64(c, s, clients_registered);
	ADD_U64(c, s, clients_reaped);
	ADD_U64(c, s, clients);
	ADD_U64(c, s, xfer_failed);
	ADD_U64(c, s, limited);
	ADD_U64(c, s, budget_refused);
	net_topic(b, line, "counters/mailbox", t, sizeof t);
	link_publish_json(b, t, o, false, NULL);
}

static void on_gw_status(bridge *b, unsigned line, const cogw_msg *m)
{
	mbx_gw_status s;
	cJSON *o, *c;
	char t[TOPIC_MAX];

	if (m->len < sizeof s)
		return;
	memcpy(&s, m->data, sizeof s);
	o = head(b, line, -1);
	c = cJSON_AddObjectToObject(o, "gateway");
	ADD_U64(c, s, sessions);
	ADD_U64(c, s, routed);
	ADD_U64(c, s, aborted);
	ADD_U64(c, s, timed_out);
	ADD_U64(c, s, refused);
	ADD_U64(c, s, relayed_frames);
	ADD_U64(c, s, pdo_published);
	ADD_U64(c, s, pdo_forwarded);
	ADD_U64(c, s, pdo_dropped);
	ADD_U64(c, s, emcy_consumed);
	ADD_U64(c, s, emcy_forwarded);
	ADD_U64(c, s, emcy_dropped);
	ADD_U64(c, s, ring_drops);
	net_topic(b, line, "counters/gateway", t, sizeof t);
	link_publish_json(b, t, o, false, NULL);
}

void events_on_internal(bridge *b, pending *p, const cogw_msg *m)
{
	if (p->cmd == MBX_CMD_DEV_WATCH) {
		mqtt_watch_answered(b, p->line, &p->watch, true, m->status);
		return;
	}
	if (m->status != 0) {
		b->st.mbx_errors++;
		if (b->verbose)
			fprintf(stderr, "cogw-mqtt: line %u: command 0x%04X: %s\n", p->line, p->cmd,
				cogw_strerror(m->status));
		return;
	}
	if (p->cmd == MBX_CMD_NODE_TABLE)
		on_node_table(b, p->line, m);
	else if (p->cmd == MBX_CMD_MGR_STATUS)
		on_mgr_status(b, p->line, m);
	else if (p->cmd == MBX_CMD_LINE_HEALTH)
		on_line_health(b, p->line, m);
	else if (p->cmd == MBX_CMD_GW_ROUTES)
		on_gw_status(b, p->line, m);
	else if (p->cmd == MBX_CMD_MGR_NODE_DIAG)
		on_node_diag(b, p->line, m);
}

static void publish_bridge_counters(bridge *b)
{
	cJSON *o = head(b, (unsigned)-1, -1), *c = cJSON_AddObjectToObject(o, "bridge");
	char t[TOPIC_MAX];

	ADD_U64(c, b->st, published);
	ADD_U64(c, b->st, queued);
	ADD_U64(c, b->st, dropped);
	ADD_U64(c, b->st, dropped_bytes);
	cJSON_AddNumberToObject(c, "queue_length", (double)b->q_len);
	ADD_U64(c, b->st, connects);
	ADD_U64(c, b->st, connect_failures);
	ADD_U64(c, b->st, disconnects);
	ADD_U64(c, b->st, events);
	ADD_U64(c, b->st, events_lost);
	ADD_U64(c, b->st, values);
	cJSON_AddNumberToObject(c, "watches", (double)b->n_watch);
	ADD_U64(c, b->st, requests);
	ADD_U64(c, b->st, replies_ok);
	ADD_U64(c, b->st, refused_role);
	ADD_U64(c, b->st, malformed);
	ADD_U64(c, b->st, too_big);
	ADD_U64(c, b->st, bad_field);
	ADD_U64(c, b->st, unknown_op);
	ADD_U64(c, b->st, rate_limited);
	ADD_U64(c, b->st, busy);
	ADD_U64(c, b->st, unsupported);
	ADD_U64(c, b->st, failed);
	ADD_U64(c, b->st, timed_out);
	ADD_U64(c, b->st, mbx_errors);
	/* what libcogw lost or could not match (docs/mailbox.md) */
	cogw_stats ls;
	size_t under_way = 0;

	cogw_get_stats(b->h, &ls);
	for (size_t i = 0; i < b->n_pend; i++)
		under_way += b->pend[i].used;
	cJSON_AddNumberToObject(c, "under_way", (double)under_way);
	cJSON_AddNumberToObject(c, "unacked", b->unacked);
	cJSON_AddNumberToObject(c, "mailbox_dropped", (double)ls.dropped_reported);
	cJSON_AddNumberToObject(c, "mailbox_async_dropped", (double)ls.async_dropped);
	cJSON_AddNumberToObject(c, "mailbox_stray", (double)ls.stray_responses);
	snprintf(t, sizeof t, "%s/%s/counters", b->cfg.topic_prefix, b->cfg.gateway);
	link_publish_json(b, t, o, false, NULL);
}

/* The state the daemon has now, for what only events would tell: the
 * manager's state and the bus health first (a slot each, before the node
 * table's diagnostics and the watches take the rest), then the node
 * table. */
static void request_state(bridge *b, unsigned line)
{
	if (b->cfg.pub_manager && b->daemon.lines[line].manager.enabled)
		bridge_send_internal(b, line, MBX_CMD_MGR_STATUS, NULL, 0);
	if (b->cfg.pub_manager)
		bridge_send_internal(b, line, MBX_CMD_LINE_HEALTH, NULL, 0);
	bridge_send_internal(b, line, MBX_CMD_NODE_TABLE, NULL, 0);
}

static void request_tables(bridge *b)
{
	for (unsigned l = 0; l < b->daemon.n_lines; l++)
		request_state(b, l);
}

void events_on_connect(bridge *b)
{
	char t[TOPIC_MAX];

	/* the broker may have lost its retained messages (restarted without
	 * persistence): what the bridge knows from memory, then all asked again */
	for (unsigned l = 0; l < b->daemon.n_lines; l++) {
		const manager_state *ms = &b->managers[l];

		if (ms->known && b->cfg.pub_manager)
			publish_manager(b, l, ms->state, -1, ms->flags);
		for (unsigned f = 0; f < MBX_FAULT_COUNT; f++)
			if (b->faults[l][f].known && b->cfg.pub_manager)
				publish_fault(b, l, &b->faults[l][f].last);
		for (unsigned n = 1; n < 128; n++) {
			node_state *ns = node_of(b, l, (uint8_t)n);

			if (ns->known && b->cfg.pub_nmt)
				publish_nmt(b, l, (uint8_t)n, ns->nmt, -1);
			if (ns->boot_json && b->cfg.pub_boot) {
				node_topic(b, l, (uint8_t)n, "boot", t, sizeof t);
				link_publish(b, t, strdup(ns->boot_json), strlen(ns->boot_json),
					     true, NULL);
			}
		}
	}
	request_tables(b);
}

void events_service(bridge *b)
{
	uint64_t now = bridge_now_ms();
	uint32_t classes = MBX_EVC_NMT | MBX_EVC_HB | MBX_EVC_BOOT | MBX_EVC_EMCY | MBX_EVC_VALUE;

	if (b->cfg.pub_manager || b->cfg.pub_boot)
		classes |= MBX_EVC_MANAGER;
	if (b->cfg.pub_manager)
		classes |= MBX_EVC_CAN | MBX_EVC_APP; /* bus health, application watchdog */
	if (now >= b->next_subscribe_ms) {
		bool all = true;

		for (unsigned l = 0; l < b->daemon.n_lines; l++) {
			if (b->subscribed[l] == classes)
				continue;
			/* answered by the mailbox server at once (docs/mailbox.md) */
			int rc = cogw_subscribe(b->h, l, classes, NULL, 0, 500);

			if (rc == 0) {
				b->subscribed[l] = classes;
				request_state(b, l);
				mqtt_watch_arm(b, l);
			} else {
				all = false;
				if (b->verbose > 1)
					fprintf(stderr, "cogw-mqtt: line %u: subscribe: %s\n", l,
						cogw_strerror(rc));
			}
		}
		b->next_subscribe_ms = all ? UINT64_MAX : now + 1000;
	}
	if (b->cfg.counters_period_s && now >= b->next_counters_ms) {
		b->next_counters_ms = now + 1000ull * b->cfg.counters_period_s;
		publish_bridge_counters(b);
		for (unsigned l = 0; l < b->daemon.n_lines; l++) {
			publish_mbx_stats(b, l);
			bridge_send_internal(b, l, MBX_CMD_GW_ROUTES, NULL, 0);
		}
		/* a state change lost with an overflowed event queue is repaired
		 * here, and the watches a restarted daemon forgot are renewed */
		request_tables(b);
		for (unsigned l = 0; l < b->daemon.n_lines; l++)
			mqtt_watch_arm(b, l);
	}
}

void events_free(bridge *b)
{
	if (!b->nodes)
		return;
	for (size_t i = 0; i < b->daemon.n_lines * 128u; i++)
		free(b->nodes[i].boot_json);
	free(b->nodes);
	b->nodes = NULL;
}
