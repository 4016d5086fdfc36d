/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-mqtt/mqtt_request.c - the request decoder (docs/mqtt.md
 * "Requests"), on the strict JSON helpers of cogwd's loader and the CiA
 * 309-3 value texts of cogw-ascii (one spelling of types for both front
 * ends).
 */
#include "apps/cogw-mqtt/mqtt_request.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "apps/cogw-mqtt/mqtt_config.h"
#include "apps/common/json_util.h"

static const char *const sdo_read_keys[] = { "op",    "id",  "reply_to", "net",        "node",
					     "index", "sub", "type",     "timeout_ms", NULL };
static const char *const sdo_write_keys[] = { "op",    "id",         "reply_to", "net",
					      "node",  "index",      "sub",      "type",
					      "value", "timeout_ms", NULL };
static const char *const nmt_keys[] = { "op", "id", "reply_to", "net", "node", "command", NULL };
static const char *const watch_keys[] = { "op",  "id",   "reply_to",        "net", "node", "index",
					  "sub", "type", "min_interval_ms", NULL };

static const struct {
	const char *name;
	mqtt_op op;
	const char *const *keys;
} ops[] = {
	{ "sdo_read", MQTT_OP_SDO_READ, sdo_read_keys },
	{ "sdo_write", MQTT_OP_SDO_WRITE, sdo_write_keys },
	{ "nmt", MQTT_OP_NMT, nmt_keys },
	{ "watch_add", MQTT_OP_WATCH_ADD, watch_keys },
	{ "watch_remove", MQTT_OP_WATCH_REMOVE, watch_keys },
};

/* CiA 301 §7.2.8.3.1 */
static const struct {
	const char *name;
	uint8_t cs;
} nmt_commands[] = {
	{ "start", 0x01 },
	{ "stop", 0x02 },
	{ "pre-operational", 0x80 },
	{ "reset-node", 0x81 },
	{ "reset-communication", 0x82 },
};

const char *mqtt_op_to_string(mqtt_op op)
{
	for (size_t i = 0; i < sizeof ops / sizeof ops[0]; i++)
		if (ops[i].op == op)
			return ops[i].name;
	return "?";
}

uint8_t mqtt_op_role(mqtt_op op)
{
	return op == MQTT_OP_SDO_WRITE || op == MQTT_OP_NMT ? MQTT_ROLE_WRITE : MQTT_ROLE_READ;
}

const char *mqtt_nmt_command_name(uint8_t cs)
{
	for (size_t i = 0; i < sizeof nmt_commands / sizeof nmt_commands[0]; i++)
		if (nmt_commands[i].cs == cs)
			return nmt_commands[i].name;
	return NULL;
}

const char *mqtt_req_err_to_string(int e)
{
	switch (e) {
	case MQTT_REQ_OK:
		return "ok";
	case MQTT_REQ_TOO_BIG:
		return "too_big";
	case MQTT_REQ_MALFORMED:
		return "malformed";
	case MQTT_REQ_BAD_OP:
		return "unknown_op";
	default:
		return "bad_field";
	}
}

/* A topic the bridge may publish a reply to: no wildcard, not a $SYS-like
 * topic, no control character. */
static bool reply_topic_ok(const char *s)
{
	if (!*s || s[0] == '$')
		return false;
	for (const unsigned char *p = (const unsigned char *)s; *p; p++)
		if (*p < 0x20 || *p == 0x7F || *p == '+' || *p == '#')
			return false;
	return true;
}

/* id and reply_to first: a refusal for any other reason still goes back
 * to the requester with them. */
static int decode_return_path(const cJSON *root, mqtt_request *r, char *err, size_t errlen)
{
	const cJSON *v = json_util_get(root, "id");
	const json_at at = { "id", err, errlen };
	const json_at at_reply_to = { "reply_to", err, errlen };

	if (v) {
		if (cJSON_IsString(v)) {
			if (json_util_string(v, &at, 1, r->id, sizeof r->id))
				return MQTT_REQ_BAD_FIELD;
		} else {
			int64_t n;

			if (json_util_sint(v, &at, -JSON_EXACT_INT_MAX, JSON_EXACT_INT_MAX, &n))
				return json_util_fail(err, errlen, "id",
						      "must be a string of 1..64 bytes or an "
						      "integer"),
				       MQTT_REQ_BAD_FIELD;
			snprintf(r->id, sizeof r->id, "%lld", (long long)n);
		}
		r->has_id = true;
	}
	v = json_util_get(root, "reply_to");
	if (v) {
		char topic[MQTT_REQ_TOPIC_MAX];

		if (json_util_string(v, &at_reply_to, 1, topic, sizeof topic))
			return MQTT_REQ_BAD_FIELD;
		if (!reply_topic_ok(topic))
			return json_util_fail(err, errlen, "reply_to",
					      "a reply topic has no '+', '#', control character "
					      "or leading '$'"),
			       MQTT_REQ_BAD_FIELD;
		memcpy(r->reply_to, topic, sizeof topic);
	}
	return 0;
}

static int need_uint(const cJSON *root, const char *key, uint64_t min, uint64_t max, bool hex,
		     uint64_t *out, char *err, size_t errlen)
{
	const cJSON *v;
	const json_at at = { "", err, errlen };
	const json_at at_key = { key, err, errlen };

	if (json_util_require(root, key, &at, &v) || json_util_uint(v, &at_key, min, max, hex, out))
		return MQTT_REQ_BAD_FIELD;
	return 0;
}

static int decode_type(const cJSON *root, mqtt_request *r, char *err, size_t errlen)
{
	const cJSON *v;
	char kw[8];
	const json_at at = { "", err, errlen };
	const json_at at_type = { "type", err, errlen };

	if (json_util_require(root, "type", &at, &v) ||
	    json_util_string(v, &at_type, 1, kw, sizeof kw))
		return MQTT_REQ_BAD_FIELD;
	r->type = ascii_type_find(kw, strlen(kw));
	if (!r->type)
		return json_util_fail(err, errlen, "type",
				      "\"%s\" is not a type (b, i8..i64, u8..u64, x8..x64, r32, "
				      "r64, t, td, vs, os, us, d, hex)",
				      kw),
		       MQTT_REQ_BAD_FIELD;
	return 0;
}

/* The object: net, node, index, sub. */
static int decode_object(const cJSON *root, mqtt_request *r, char *err, size_t errlen)
{
	uint64_t net, node, index, sub;

	if (need_uint(root, "net", 1, 127, false, &net, err, errlen) ||
	    need_uint(root, "node", 1, 127, false, &node, err, errlen) ||
	    need_uint(root, "index", 0, 0xFFFF, true, &index, err, errlen) ||
	    need_uint(root, "sub", 0, 255, false, &sub, err, errlen))
		return MQTT_REQ_BAD_FIELD;
	r->net = (uint16_t)net;
	r->node = (uint8_t)node;
	r->index = (uint16_t)index;
	r->sub = (uint8_t)sub;
	return decode_type(root, r, err, errlen);
}

/* "value" into wire bytes: a string is the value's text (vs: the string
 * itself), a number an integer or real, true/false a BOOLEAN. */
static int decode_value(const cJSON *root, mqtt_request *r, char *err, size_t errlen)
{
	const cJSON *v;
	char text[64];
	const char *s;
	size_t n;
	int rc;
	const json_at at = { "", err, errlen };

	if (json_util_require(root, "value", &at, &v))
		return MQTT_REQ_BAD_FIELD;
	if (cJSON_IsString(v)) {
		s = v->valuestring;
		n = strlen(s);
	} else if (cJSON_IsBool(v)) {
		s = cJSON_IsTrue(v) ? "1" : "0";
		n = 1;
	} else if (cJSON_IsNumber(v)) {
		double d = v->valuedouble;

		if (!isfinite(d))
			return json_util_fail(err, errlen, "value", "not a finite number"),
			       MQTT_REQ_BAD_FIELD;
		if (r->type->kind == ASCII_K_REAL32 || r->type->kind == ASCII_K_REAL64)
			snprintf(text, sizeof text, "%.17g", d);
		else if (d == floor(d) && fabs(d) <= JSON_EXACT_INT_MAX)
			snprintf(text, sizeof text, "%.0f", d);
		else
			return json_util_fail(err, errlen, "value",
					      "an integer type needs an integer within +-2^53 (a "
					      "string for larger ones)"),
			       MQTT_REQ_BAD_FIELD;
		s = text;
		n = strlen(text);
	} else {
		return json_util_fail(err, errlen, "value",
				      "must be a string, a number or true/false, not %s",
				      json_util_kind(v)),
		       MQTT_REQ_BAD_FIELD;
	}
	rc = ascii_value_encode(r->type, s, n, r->value, sizeof r->value, &r->value_len);
	if (rc == -ERANGE)
		return json_util_fail(err, errlen, "value", "out of the range of %s",
				      r->type->keyword),
		       MQTT_REQ_BAD_FIELD;
	if (rc == -E2BIG)
		return json_util_fail(err, errlen, "value", "more than %u bytes",
				      MQTT_REQ_VALUE_MAX),
		       MQTT_REQ_BAD_FIELD;
	if (rc)
		return json_util_fail(err, errlen, "value", "not a value of type %s",
				      r->type->keyword),
		       MQTT_REQ_BAD_FIELD;
	return 0;
}

static int decode_nmt(const cJSON *root, mqtt_request *r, char *err, size_t errlen)
{
	uint64_t net, node;
	const cJSON *v;
	char cmd[24];
	const json_at at = { "", err, errlen };
	const json_at at_command = { "command", err, errlen };

	if (need_uint(root, "net", 1, 127, false, &net, err, errlen) ||
	    need_uint(root, "node", 0, 127, false, &node, err, errlen) ||
	    json_util_require(root, "command", &at, &v) ||
	    json_util_string(v, &at_command, 1, cmd, sizeof cmd))
		return MQTT_REQ_BAD_FIELD;
	r->net = (uint16_t)net;
	r->node = (uint8_t)node;
	for (size_t i = 0; i < sizeof nmt_commands / sizeof nmt_commands[0]; i++)
		if (strcmp(cmd, nmt_commands[i].name) == 0) {
			r->nmt_cs = nmt_commands[i].cs;
			return 0;
		}
	return json_util_fail(err, errlen, "command",
			      "\"%s\" is not one of start, stop, pre-operational, reset-node, "
			      "reset-communication",
			      cmd),
	       MQTT_REQ_BAD_FIELD;
}

static int decode_tree(const cJSON *root, mqtt_request *r, char *err, size_t errlen)
{
	const cJSON *v;
	char op[16];
	size_t i;
	uint64_t u;
	int rc;
	const json_at at = { "", err, errlen };
	const json_at at_op = { "op", err, errlen };

	if (!cJSON_IsObject(root))
		return json_util_fail(err, errlen, "(top)", "must be an object, not %s",
				      json_util_kind(root)),
		       MQTT_REQ_MALFORMED;
	rc = decode_return_path(root, r, err, errlen);
	if (rc)
		return rc;
	if (json_util_require(root, "op", &at, &v) || json_util_string(v, &at_op, 1, op, sizeof op))
		return MQTT_REQ_BAD_OP;
	for (i = 0; i < sizeof ops / sizeof ops[0]; i++)
		if (strcmp(op, ops[i].name) == 0)
			break;
	if (i == sizeof ops / sizeof ops[0])
		return json_util_fail(err, errlen, "op",
				      "\"%s\" is not one of sdo_read, sdo_write, nmt, watch_add, "
				      "watch_remove",
				      op),
		       MQTT_REQ_BAD_OP;
	r->op = ops[i].op;
	if (json_util_check_object(root, &at, ops[i].keys))
		return MQTT_REQ_BAD_FIELD;
	if (r->op == MQTT_OP_NMT)
		return decode_nmt(root, r, err, errlen);
	rc = decode_object(root, r, err, errlen);
	if (rc)
		return rc;
	u = 0;
	if (json_util_opt_uint(root, "timeout_ms", &at, 1, 600000, &u))
		return MQTT_REQ_BAD_FIELD;
	r->sdo_timeout_ms = (uint32_t)u;
	u = 1000;
	if (json_util_opt_uint(root, "min_interval_ms", &at, 0, 3600000, &u))
		return MQTT_REQ_BAD_FIELD;
	r->min_interval_ms = (uint32_t)u;
	if (r->op == MQTT_OP_SDO_WRITE)
		return decode_value(root, r, err, errlen);
	return 0;
}

int mqtt_request_decode(const void *payload, size_t len, size_t max_payload, mqtt_request *r,
			char *err, size_t errlen)
{
	cJSON *root = NULL;
	char *text;
	int rc;

	memset(r, 0, offsetof(mqtt_request, value));
	r->value_len = 0;
	if (len > max_payload) {
		snprintf(err, errlen, "the payload has %zu bytes, the limit is %zu", len,
			 max_payload);
		return MQTT_REQ_TOO_BIG;
	}
	if (len == 0 || memchr(payload, 0, len)) {
		snprintf(err, errlen, "(top): %s",
			 len ? "a NUL byte in the payload" : "empty payload");
		return MQTT_REQ_MALFORMED;
	}
	text = malloc(len + 1);
	if (!text) {
		snprintf(err, errlen, "out of memory");
		return MQTT_REQ_MALFORMED;
	}
	memcpy(text, payload, len);
	text[len] = 0;
	rc = json_util_parse(text, &root, err, errlen) ? MQTT_REQ_MALFORMED
						       : decode_tree(root, r, err, errlen);
	cJSON_Delete(root);
	free(text);
	return rc;
}
