/* SPDX-License-Identifier: MIT */
/*
 * gateway/gw_status.c - what the gateway tells about itself: the mailbox's
 * GW_ROUTES answer (the routing table with its counters, the routed
 * sessions running) and the counters of a line for any thread.
 */
#include <stdio.h>
#include <string.h>

#include "gateway/gw_line.h"
#include "mailbox/proto.h"
#include "mailbox/server.h"

/* The routed sessions running on this line, after the routes. */
static size_t list_sessions(struct gw_line *gl, uint8_t *out, uint8_t *count)
{
	uint64_t now_us = line_loop_now_us(gl->l);
	size_t off = 0;

	*count = 0;
	for (uint8_t i = 0; i < gl->n_sess; i++) {
		const struct gw_sess *s = &gl->sess[i];
		mbx_gw_session e = { .channel = i, .target_line = 0xFF };

		if (!gw_sdo_route_busy(&s->r))
			continue;
		if (s->r.opened)
			e.target_line = s->target_line;
		e.router = s->r.hop.via_router ? s->r.hop.node : 0;
		e.node = s->r.target.node;
		e.net = s->net;
		e.age_ms = (uint32_t)((now_us - s->started_us) / 1000u);
		e.frames = (uint32_t)(s->r.frames_to_target + s->r.frames_to_requester);
		snprintf(e.state, sizeof e.state, "%s",
			 gw_sdo_route_state_to_string(gw_sdo_route_state_of(&s->r)));
		memcpy(out + off, &e, sizeof e);
		off += sizeof e;
		(*count)++;
	}
	return off;
}

void gw_mbx_routes(struct gw_line *gl, const mbx_request *req)
{
	static __thread uint8_t buf[sizeof(mbx_gw_status) + GW_NET_MAX * sizeof(mbx_gw_route) +
				    255 * sizeof(mbx_gw_session)];
	mbx_gw_status st = { .network_id = gl->p.network_id };
	gw_line_counters c;
	size_t off = sizeof st;

	gw_line_counters_get(gl->g, gl->idx, &c);
	st.sessions = c.sessions;
	st.routed = c.routed;
	st.aborted = c.aborted;
	st.timed_out = c.timed_out;
	st.refused = c.refused;
	st.relayed_frames = c.relayed_frames;
	st.pdo_published = c.pdo_published;
	st.pdo_forwarded = c.pdo_forwarded;
	st.pdo_dropped = c.pdo_dropped;
	st.pdo_applied = c.pdo_applied;
	st.pdo_triggered = c.pdo_triggered;
	st.emcy_consumed = c.emcy.consumed;
	st.emcy_forwarded = c.emcy.forwarded;
	st.emcy_unroutable = c.emcy.unroutable;
	st.emcy_dropped = c.emcy.dropped;
	st.emcy_sent = c.emcy.sent;
	st.ring_drops = c.ring_drops;
	st.pdo_fast = c.pdo_fast;
	st.sdo_across = c.sdo_across;
	for (unsigned i = 0; i < GW_RELAYS_MAX; i++)
		st.leases += gl->relay[i].used;
	for (unsigned n = GW_NET_MIN; n <= GW_NET_MAX; n++) {
		const gw_route *r = &gl->routes.r[n];
		mbx_gw_route e = { .net = (uint8_t)n,
				   .kind = r->kind,
				   .line = r->line,
				   .router = r->router,
				   .raw = r->raw,
				   .routed = r->count[GW_OUT_ROUTED],
				   .aborted = r->count[GW_OUT_ABORTED],
				   .timed_out = r->count[GW_OUT_TIMED_OUT],
				   .refused = r->count[GW_OUT_REFUSED] };
		if (r->kind == GW_ROUTE_NONE && !e.routed && !e.aborted && !e.timed_out &&
		    !e.refused)
			continue;
		memcpy(buf + off, &e, sizeof e);
		off += sizeof e;
		st.routes++;
	}
	off += list_sessions(gl, buf + off, &st.active);
	memcpy(buf, &st, sizeof st);
	mbx_server_respond(line_mbx(gl->l), &req->reply, 0, 0, buf, off);
}

void gw_line_counters_get(gw *g, unsigned line_no, gw_line_counters *out)
{
	const uint64_t *src;
	uint64_t *dst = (uint64_t *)out;

	memset(out, 0, sizeof(*out));
	if (!g || line_no >= g->n)
		return;
	src = (const uint64_t *)&g->line[line_no].c;
	for (size_t i = 0; i < sizeof(*out) / sizeof(uint64_t); i++)
		dst[i] = __atomic_load_n(&src[i], __ATOMIC_RELAXED);
}
