/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-mqtt/mqtt_watch.c - process values (mqtt_watch.h).
 */
#include "apps/cogw-mqtt/mqtt_watch.h"

#include <cjson/cJSON.h>
#include <stdio.h>
#include <string.h>

mqtt_watch_cfg mqtt_watch_of(const mqtt_request *r)
{
	return (mqtt_watch_cfg){ .net = r->net,
				 .node = r->node,
				 .sub = r->sub,
				 .index = r->index,
				 .min_interval_ms = r->min_interval_ms,
				 .type = r->type };
}

size_t mqtt_watch_command(const mqtt_watch_cfg *w, bool add, uint16_t *cmd, void *payload)
{
	/* type 0: the daemon's own knowledge of the object (the device's
	 * DCF/EDS); the bridge shows the bytes as the watch's type says */
	mbx_dev_watch_req q = { .obj = { .node = w->node, .sub = w->sub, .index = w->index },
				.min_interval_ms = w->min_interval_ms };

	if (add) {
		*cmd = MBX_CMD_DEV_WATCH;
		memcpy(payload, &q, sizeof q);
		return sizeof q;
	}
	*cmd = MBX_CMD_DEV_UNWATCH;
	memcpy(payload, &q.obj, sizeof q.obj);
	return sizeof q.obj;
}

static bridge_watch *find(bridge *b, unsigned line, uint8_t node, uint16_t index, uint8_t sub)
{
	for (size_t i = 0; i < b->n_watch; i++) {
		bridge_watch *w = &b->watch[i];

		if (w->line == line && w->w.node == node && w->w.index == index && w->w.sub == sub)
			return w;
	}
	return NULL;
}

static bool same_object(const mqtt_watch_cfg *a, const mqtt_watch_cfg *b)
{
	return a->net == b->net && a->node == b->node && a->index == b->index && a->sub == b->sub;
}

void mqtt_watch_answered(bridge *b, unsigned line, const mqtt_watch_cfg *w, bool add, int status)
{
	bridge_watch *known = find(b, line, w->node, w->index, w->sub);

	for (unsigned i = 0; i < b->cfg.n_watch; i++) {
		const mqtt_watch_cfg *c = &b->cfg.watch[i];

		/* a configured watch has nobody else to tell: the log, once per
		 * change (it is renewed every counters period) */
		if (add && same_object(c, w))
			b->cfg_watch_answered[i] = true;
		if (add && same_object(c, w) && b->cfg_watch_status[i] != status) {
			b->cfg_watch_status[i] = status;
			fprintf(stderr, "cogw-mqtt: watch of net %u node %u %04X:%02X: %s\n",
				w->net, w->node, w->index, w->sub,
				status ? mqtt_watch_refusal(status) : "watching");
		}
	}
	if (status)
		return;
	/* a configured watch removed by request stays removed until it is
	 * added again (or the bridge restarts) */
	for (unsigned i = 0; i < b->cfg.n_watch; i++) {
		const mqtt_watch_cfg *c = &b->cfg.watch[i];

		if (same_object(c, w))
			b->cfg_watch_removed[i] = !add;
	}
	if (!add) {
		if (known)
			*known = b->watch[--b->n_watch];
		return;
	}
	if (!known && b->n_watch < MQTT_WATCH_MAX) {
		known = &b->watch[b->n_watch++];
		known->line = (uint8_t)line;
	}
	if (known)
		known->w = *w;
}

static bool send_watch(bridge *b, unsigned line, const mqtt_watch_cfg *w)
{
	uint8_t payload[sizeof(mbx_dev_watch_req)];
	uint16_t cmd;
	size_t len = mqtt_watch_command(w, true, &cmd, payload);
	pending *p = bridge_send_internal(b, line, cmd, payload, len);

	if (p)
		p->watch = *w;
	return p != NULL;
}

static bool watch_under_way(const bridge *b, unsigned line, const mqtt_watch_cfg *w)
{
	for (size_t i = 0; i < b->n_pend; i++) {
		const pending *p = &b->pend[i];

		if (p->used && p->internal && p->cmd == MBX_CMD_DEV_WATCH && p->line == line &&
		    same_object(&p->watch, w))
			return true;
	}
	return false;
}

/* The configured watches of a line that are not in force nor under way
 * (only_new: nor answered before - a refused one waits for the next
 * period), until the bridge's request slots are taken. */
static void arm_configured(bridge *b, unsigned line, bool only_new)
{
	for (unsigned i = 0; i < b->cfg.n_watch; i++) {
		const mqtt_watch_cfg *w = &b->cfg.watch[i];

		if (bridge_line_of_net(b, w->net) != (int)line || b->cfg_watch_removed[i] ||
		    (only_new && b->cfg_watch_answered[i]) ||
		    find(b, line, w->node, w->index, w->sub) || watch_under_way(b, line, w))
			continue;
		if (!send_watch(b, line, w))
			return; /* the rest when answers free the slots */
	}
}

void mqtt_watch_arm(bridge *b, unsigned line)
{
	/* the watches in force again (watching again only renews them: a
	 * restarted daemon knows none), then the configured ones not yet */
	for (size_t i = 0; i < b->n_watch; i++)
		if (b->watch[i].line == line)
			send_watch(b, line, &b->watch[i].w);
	arm_configured(b, line, false);
}

void mqtt_watch_arm_rest(bridge *b, unsigned line)
{
	arm_configured(b, line, true);
}

const char *mqtt_watch_refusal(int status)
{
	switch (status) {
	case COGW_E_UNKNOWN_CMD:
	case COGW_E_UNSUPPORTED:
		return "the daemon does not serve watches of device objects (docs/mqtt.md "
		       "\"Process values\")";
	case COGW_E_NOT_FOUND:
		return "no TPDO of the node maps the object (docs/config.md \"PDO layouts\")";
	case COGW_E_STATE:
		return "the node's PDOs are not mirrored (its \"pdo\" is not \"auto\")";
	case COGW_E_FULL:
		return "the line's watch table is full";
	default:
		return cogw_strerror(status);
	}
}

void mqtt_watch_on_value(bridge *b, const cogw_msg *m)
{
	mbx_dev_value v;
	bridge_watch *w;
	cJSON *o, *val;
	char t[512], s[16], why[128];

	if (m->len < sizeof v || m->line >= b->daemon.n_lines)
		return;
	memcpy(&v, m->data, sizeof v);
	if (m->len != sizeof v + v.len)
		return;
	w = find(b, m->line, v.node, v.index, v.sub);
	if (!w)
		return; /* a watch removed while its value was under way */
	val = bridge_value_json(w->w.type, m->data + sizeof v, v.len, why, sizeof why);
	if (!val) {
		b->st.failed++;
		if (b->verbose)
			fprintf(stderr, "cogw-mqtt: value of node %u %04X:%02X: %s\n", v.node,
				v.index, v.sub, why);
		return;
	}
	o = cJSON_CreateObject();
	bridge_time_text(t, sizeof t);
	cJSON_AddStringToObject(o, "time", t);
	cJSON_AddStringToObject(o, "gateway", b->cfg.gateway);
	cJSON_AddNumberToObject(o, "net", w->w.net);
	cJSON_AddNumberToObject(o, "node", v.node);
	snprintf(s, sizeof s, "0x%04X", v.index);
	cJSON_AddStringToObject(o, "index", s);
	cJSON_AddNumberToObject(o, "sub", v.sub);
	cJSON_AddStringToObject(o, "type", w->w.type->keyword);
	cJSON_AddItemToObject(o, "value", val);
	cJSON_AddStringToObject(o, "via", v.via == MBX_DEV_VIA_PDO ? "pdo" : "sdo");
	cJSON_AddNumberToObject(o, "seq", v.seq);
	snprintf(t, sizeof t, "%s/%s/net/%u/node/%u/value/%04X/%u", b->cfg.topic_prefix,
		 b->cfg.gateway, w->w.net, v.node, v.index, v.sub);
	b->st.values++;
	link_publish_json(b, t, o, true, NULL);
}
