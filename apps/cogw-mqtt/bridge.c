/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-mqtt/bridge.c - what every part of the bridge uses (bridge.h):
 * the clocks, the line of a network, the slots of the requests under way
 * in the daemon, and a value as JSON. The bottom of the program: it calls
 * nothing above it.
 */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "apps/cogw-mqtt/bridge.h"
#include "apps/common/mbx_loop.h"
#include "apps/common/json_util.h"

/* ---- clocks ---- */

uint64_t bridge_now_ms(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

uint64_t bridge_wall_ms(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_REALTIME, &ts);
	return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

void bridge_time_of(uint64_t wall_ms, char *buf, size_t n)
{
	time_t sec = (time_t)(wall_ms / 1000u);
	struct tm tm;
	size_t k;

	gmtime_r(&sec, &tm);
	k = strftime(buf, n, "%Y-%m-%dT%H:%M:%S", &tm);
	snprintf(buf + k, n - k, ".%03uZ", (unsigned)(wall_ms % 1000u));
}

void bridge_time_text(char *buf, size_t n)
{
	bridge_time_of(bridge_wall_ms(), buf, n);
}

int bridge_line_of_net(const bridge *b, uint16_t net)
{
	for (size_t l = 0; l < b->daemon.n_lines; l++)
		if (b->daemon.lines[l].network_id == net)
			return (int)l;
	return -1;
}

/* ---- requests under way in the daemon ---- */

pending *bridge_pending_of(bridge *b, uint64_t corr)
{
	for (size_t i = 0; i < b->n_pend; i++)
		if (b->pend[i].used && b->pend[i].corr == corr)
			return &b->pend[i];
	return NULL;
}

void bridge_pending_release(pending *p)
{
	free(p->reply_topic);
	mosquitto_property_free_all(&p->reply_props);
	p->reply_topic = NULL;
	p->used = false;
}

int bridge_send(bridge *b, unsigned line, uint16_t cmd, const void *payload, size_t len,
		uint64_t *corr)
{
	/* the bridge's own deadline (serve_expire) answers first; libcogw's,
	 * a second later, only ends its bookkeeping of a reply that never came */
	return mbx_loop_send(b->h, line, cmd, payload, len, b->cfg.request_timeout_ms + 1000u,
			     corr);
}

/* The bridge's own requests have slots after the requests' ones. */
pending *bridge_send_internal(bridge *b, unsigned line, uint16_t cmd, const void *payload,
			      size_t len)
{
	for (size_t i = b->cfg.max_inflight; i < b->n_pend; i++) {
		pending *p = &b->pend[i];

		if (p->used)
			continue;
		int rc = bridge_send(b, line, cmd, payload, len, &p->corr);

		if (rc < 0) {
			b->st.mbx_errors++;
			if (b->verbose > 1)
				fprintf(stderr, "cogw-mqtt: line %u: command 0x%04X: %s\n", line,
					cmd, cogw_strerror(rc));
			return NULL;
		}
		p->used = p->internal = true;
		p->cmd = cmd;
		p->line = (uint8_t)line;
		p->deadline_ms = bridge_now_ms() + b->cfg.request_timeout_ms;
		return p;
	}
	b->st.busy++;
	return NULL;
}

/* ---- values ---- */

/* The value read, as JSON: numbers where JSON carries them exactly. */
cJSON *bridge_value_json(const ascii_type *t, const uint8_t *data, size_t len, char *err,
			 size_t errlen)
{
	size_t cap = ascii_value_text_max(t, len) + 1;
	char *text;
	long n;
	cJSON *v = NULL;

	if (t->kind == ASCII_K_VSTRING) {
		/* VISIBLE_STRING: the characters themselves, up to a NUL */
		text = strndup((const char *)data, len);
		v = text ? cJSON_CreateString(text) : NULL;
		free(text);
		return v;
	}
	text = malloc(cap);
	if (!text)
		return NULL;
	n = ascii_value_format(t, data, len, text, cap);
	if (n < 0) {
		snprintf(err, errlen, "the device answered %zu bytes, not a value of type %s", len,
			 t->keyword);
	} else if (t->kind == ASCII_K_BOOL) {
		v = cJSON_CreateBool(text[0] == '1');
	} else if ((t->kind == ASCII_K_INT || t->kind == ASCII_K_UINT) &&
		   fabs(strtod(text, NULL)) <= 9007199254740992.0) {
		v = cJSON_CreateNumber(strtod(text, NULL));
	} else if ((t->kind == ASCII_K_REAL32 || t->kind == ASCII_K_REAL64) &&
		   isfinite(strtod(text, NULL))) {
		v = json_util_real_number(text);
	} else {
		v = cJSON_CreateString(text);
	}
	free(text);
	return v;
}
