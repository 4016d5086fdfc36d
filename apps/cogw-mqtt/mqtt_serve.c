/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-mqtt/mqtt_serve.c - requests from the broker (docs/mqtt.md
 * "Requests"): decoded and checked (mqtt_request.c), held against the
 * bridge's role and its flood and in-flight limits, sent to the daemon
 * without waiting (cogw_loop_send) and answered when the mailbox answer
 * comes: MQTT 5 request/response (response topic and correlation data of
 * the request), or for MQTT 3.1.1 clients the request's reply_to and id.
 */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "apps/cogw-mqtt/bridge.h"
#include "apps/cogw-mqtt/mqtt_watch.h"
#include "core/sdo.h"

/* Where a reply goes and what it carries back. */
typedef struct reply_path {
	char *topic;
	mosquitto_property *props;
} reply_path;

static cJSON *reply_head(const bridge *b, const mqtt_request *r, bool ok)
{
	cJSON *o = cJSON_CreateObject();
	char t[40];

	bridge_time_text(t, sizeof t);
	cJSON_AddStringToObject(o, "time", t);
	cJSON_AddStringToObject(o, "gateway", b->cfg.gateway);
	if (r->has_id)
		cJSON_AddStringToObject(o, "id", r->id);
	cJSON_AddBoolToObject(o, "ok", ok);
	return o;
}

static void add_object(cJSON *o, const mqtt_request *r)
{
	char s[8];

	cJSON_AddStringToObject(o, "op", mqtt_op_to_string(r->op));
	cJSON_AddNumberToObject(o, "net", r->net);
	cJSON_AddNumberToObject(o, "node", r->node);
	if (r->op == MQTT_OP_NMT) {
		cJSON_AddStringToObject(o, "command", mqtt_nmt_command_name(r->nmt_cs));
		return;
	}
	snprintf(s, sizeof s, "0x%04X", r->index);
	cJSON_AddStringToObject(o, "index", s);
	cJSON_AddNumberToObject(o, "sub", r->sub);
	if (r->type)
		cJSON_AddStringToObject(o, "type", r->type->keyword);
}

static void send_reply(bridge *b, reply_path *rp, cJSON *o)
{
	link_publish_json(b, rp->topic, o, false, rp->props);
	rp->props = NULL;
	free(rp->topic);
	rp->topic = NULL;
}

/* A refusal: error is one of the names of docs/mqtt.md "Errors". */
static void refuse(bridge *b, reply_path *rp, const mqtt_request *r, bool decoded,
		   const char *error, const char *reason)
{
	cJSON *o = reply_head(b, r, false);

	if (decoded)
		add_object(o, r);
	cJSON_AddStringToObject(o, "error", error);
	cJSON_AddStringToObject(o, "reason", reason);
	if (b->verbose)
		fprintf(stderr, "cogw-mqtt: request refused: %s: %s\n", error, reason);
	send_reply(b, rp, o);
}

static bool take_token(bridge *b)
{
	uint64_t now = bridge_now_ms();
	double cap = b->cfg.requests_per_s;

	b->tokens += (double)(now - b->tokens_ms) * cap / 1000.0;
	if (b->tokens > cap)
		b->tokens = cap;
	b->tokens_ms = now;
	if (b->tokens < 1.0)
		return false;
	b->tokens -= 1.0;
	return true;
}

static pending *free_slot(bridge *b)
{
	for (size_t i = 0; i < b->cfg.max_inflight; i++)
		if (!b->pend[i].used)
			return &b->pend[i];
	return NULL;
}

/* The request into the daemon. 0, or a refusal already sent. */
static int start_request(bridge *b, reply_path *rp, const mqtt_request *r)
{
	uint8_t payload[sizeof(mbx_gw_sdo_req) + MQTT_REQ_VALUE_MAX];
	size_t len;
	uint16_t cmd;
	int line = bridge_line_of_net(b, r->net);
	pending *p = free_slot(b);
	char why[256];

	if (!p) {
		b->st.busy++;
		snprintf(why, sizeof why,
			 "%u requests are under way, the limit of requests.max_inflight",
			 b->cfg.max_inflight);
		refuse(b, rp, r, true, "busy", why);
		return -1;
	}
	if (line < 0 && r->op != MQTT_OP_SDO_READ && r->op != MQTT_OP_SDO_WRITE) {
		b->st.bad_field++;
		snprintf(why, sizeof why,
			 "network %u is not attached to gateway %s: %s goes through the gateway "
			 "of that network",
			 r->net, b->cfg.gateway, mqtt_op_to_string(r->op));
		refuse(b, rp, r, true, "unknown_network", why);
		return -1;
	}
	if (r->op == MQTT_OP_WATCH_ADD || r->op == MQTT_OP_WATCH_REMOVE) {
		p->watch = mqtt_watch_of(r);
		len = mqtt_watch_command(&p->watch, r->op == MQTT_OP_WATCH_ADD, &cmd, payload);
	} else if (r->op == MQTT_OP_NMT) {
		mbx_nmt_req q = { .cs = r->nmt_cs, .node = r->node };

		cmd = MBX_CMD_NMT;
		memcpy(payload, &q, sizeof q);
		len = sizeof q;
	} else {
		/* an attached network: the plain SDO transfer on its line, as
		 * cogw-ascii and cogwctl do, so that each situation has one
		 * answer in every front end (docs/sdo-answers.md); any other
		 * network: the line's routing table (1F2Ch) takes it there
		 * (docs/gateway.md) */
		mbx_gw_sdo_req q = { .net = r->net,
				     .sdo = { .node = r->node,
					      .index = r->index,
					      .sub = r->sub,
					      .timeout_ms = r->sdo_timeout_ms } };
		bool read = r->op == MQTT_OP_SDO_READ;

		if (line >= 0) {
			cmd = read ? MBX_CMD_SDO_UPLOAD : MBX_CMD_SDO_DOWNLOAD;
			memcpy(payload, &q.sdo, sizeof q.sdo);
			len = sizeof q.sdo;
		} else {
			line = (int)b->cfg.route_line;
			cmd = read ? MBX_CMD_GW_SDO_UPLOAD : MBX_CMD_GW_SDO_DOWNLOAD;
			memcpy(payload, &q, sizeof q);
			len = sizeof q;
		}
		if (r->op == MQTT_OP_SDO_WRITE) {
			memcpy(payload + len, r->value, r->value_len);
			len += r->value_len;
		}
	}
	int rc = bridge_send(b, (unsigned)line, cmd, payload, len, &p->corr);

	if (rc == COGW_E_WOULDBLOCK) {
		b->st.busy++;
		snprintf(why, sizeof why, "the daemon's command queue of line %d is full", line);
		refuse(b, rp, r, true, "busy", why);
		return -1;
	}
	if (rc < 0) {
		b->st.mbx_errors++;
		snprintf(why, sizeof why, "the daemon's mailbox: %s", cogw_strerror(rc));
		refuse(b, rp, r, true, "daemon", why);
		return -1;
	}
	p->used = true;
	p->internal = false;
	p->cmd = cmd;
	p->line = (uint8_t)line;
	p->deadline_ms = bridge_now_ms() + b->cfg.request_timeout_ms;
	p->req = *r;
	p->reply_topic = rp->topic;
	p->reply_props = rp->props;
	rp->topic = NULL;
	rp->props = NULL;
	return 0;
}

void serve_on_message(bridge *b, const struct mosquitto_message *msg,
		      const mosquitto_property *props)
{
	static mqtt_request r;
	reply_path rp = { 0 };
	char *rt = NULL, err[512];
	void *cd = NULL;
	uint16_t cd_len = 0;
	int rc;

	if (strcmp(msg->topic, b->topic_request) != 0)
		return;
	b->st.requests++;
	if (props) {
		mosquitto_property_read_string(props, MQTT_PROP_RESPONSE_TOPIC, &rt, false);
		if (mosquitto_property_read_binary(props, MQTT_PROP_CORRELATION_DATA, &cd, &cd_len,
						   false))
			mosquitto_property_add_binary(&rp.props, MQTT_PROP_CORRELATION_DATA, cd,
						      cd_len);
		free(cd);
	}
	if (!take_token(b)) {
		/* nothing of the payload is looked at: a flood costs no parsing */
		memset(&r, 0, offsetof(mqtt_request, value));
		b->st.rate_limited++;
		rp.topic = rt ? rt : strdup(b->topic_response);
		snprintf(err, sizeof err, "more than %u requests per second (requests.per_second)",
			 b->cfg.requests_per_s);
		refuse(b, &rp, &r, false, "rate_limited", err);
		return;
	}
	rc = mqtt_request_decode(msg->payload, (size_t)msg->payloadlen, b->cfg.max_payload, &r, err,
				 sizeof err);
	rp.topic = rt ? rt : strdup(r.reply_to[0] ? r.reply_to : b->topic_response);
	if (rc) {
		uint64_t *count = rc == MQTT_REQ_TOO_BIG     ? &b->st.too_big
				  : rc == MQTT_REQ_MALFORMED ? &b->st.malformed
				  : rc == MQTT_REQ_BAD_OP    ? &b->st.unknown_op
							     : &b->st.bad_field;

		(*count)++;
		refuse(b, &rp, &r, false, mqtt_req_err_to_string(rc), err);
		return;
	}
	if (mqtt_op_role(r.op) > b->cfg.role) {
		b->st.refused_role++;
		snprintf(err, sizeof err, "%s needs role %s; gateway %s's bridge has role %s",
			 mqtt_op_to_string(r.op), mqtt_role_to_string(mqtt_op_role(r.op)),
			 b->cfg.gateway, mqtt_role_to_string(b->cfg.role));
		refuse(b, &rp, &r, true, "refused_role", err);
		return;
	}
	if (start_request(b, &rp, &r)) {
		free(rp.topic);
		mosquitto_property_free_all(&rp.props);
	}
}

void serve_on_response(bridge *b, pending *p, const cogw_msg *m)
{
	reply_path rp = { .topic = p->reply_topic, .props = p->reply_props };
	const mqtt_request *r = &p->req;
	char why[256];

	p->reply_topic = NULL;
	p->reply_props = NULL;
	if (r->op == MQTT_OP_WATCH_ADD || r->op == MQTT_OP_WATCH_REMOVE)
		mqtt_watch_answered(b, p->line, &p->watch, r->op == MQTT_OP_WATCH_ADD, m->status);
	if ((r->op == MQTT_OP_WATCH_ADD || r->op == MQTT_OP_WATCH_REMOVE) &&
	    (m->status == COGW_E_UNKNOWN_CMD || m->status == COGW_E_UNSUPPORTED)) {
		b->st.unsupported++;
		refuse(b, &rp, r, true, "unsupported", mqtt_watch_refusal(m->status));
	} else if ((r->op == MQTT_OP_WATCH_ADD || r->op == MQTT_OP_WATCH_REMOVE) && m->status &&
		   m->status != COGW_E_ABORT) {
		b->st.failed++;
		refuse(b, &rp, r, true, "watch_refused", mqtt_watch_refusal(m->status));
	} else if (m->status == COGW_E_ABORT) {
		cJSON *o = reply_head(b, r, false);
		char s[16];

		add_object(o, r);
		b->st.failed++;
		cJSON_AddStringToObject(o, "error", "abort");
		snprintf(s, sizeof s, "0x%08X", m->abort);
		cJSON_AddStringToObject(o, "abort", s);
		cJSON_AddStringToObject(o, "reason", sdo_abort_to_string(m->abort));
		send_reply(b, &rp, o);
	} else if (m->status != 0) {
		b->st.failed++;
		snprintf(why, sizeof why, "the daemon: %s", cogw_strerror(m->status));
		refuse(b, &rp, r, true, "daemon", why);
	} else {
		cJSON *o = reply_head(b, r, true), *v = NULL;

		add_object(o, r);
		if (r->op == MQTT_OP_SDO_READ) {
			why[0] = 0;
			v = bridge_value_json(r->type, m->data, m->len, why, sizeof why);
			if (!v) {
				cJSON_Delete(o);
				b->st.failed++;
				refuse(b, &rp, r, true, "type_mismatch",
				       why[0] ? why : "out of memory");
				bridge_pending_release(p);
				return;
			}
			cJSON_AddItemToObject(o, "value", v);
		}
		b->st.replies_ok++;
		send_reply(b, &rp, o);
	}
	bridge_pending_release(p);
}

void serve_expire(bridge *b)
{
	uint64_t now = bridge_now_ms();
	char why[128];

	for (size_t i = 0; i < b->n_pend; i++) {
		pending *p = &b->pend[i];

		if (!p->used || now < p->deadline_ms)
			continue;
		b->st.timed_out++;
		if (!p->internal) {
			reply_path rp = { .topic = p->reply_topic, .props = p->reply_props };

			p->reply_topic = NULL;
			p->reply_props = NULL;
			snprintf(why, sizeof why, "no answer from the daemon within %u ms",
				 b->cfg.request_timeout_ms);
			refuse(b, &rp, &p->req, true, "timeout", why);
		}
		bridge_pending_release(p);
	}
}
