/* SPDX-License-Identifier: MIT */
/*
 * gateway/gw_session.c - routed sessions on the entry line: a network
 * indication on the line's SDO server (core/sdo_server.h routing hook)
 * starts one, gateway/sdo_route.h runs it, and its frames go to the
 * target line's relay lease (gw_relay.c) as messages. The session owns the
 * server channel and the timers; the lease owns the client channel.
 * A frame for the target normally leaves from here, on this thread's
 * socket bound to the target line's interface, the message only telling
 * the lease (gw_send_across); the lease sends the target's answers to
 * the requester the same way, and its message feeds the session's state
 * with a frame that is already out (answered_across).
 */
#include <string.h>

#include "core/sdo_server.h"
#include "gateway/gw_line.h"
#include "mailbox/server.h"

static uint32_t sid_of(const struct gw_sess *s)
{
	return (uint32_t)s->gl->idx << 24 | (uint32_t)s->ch << 16 | s->gen;
}

static struct gw_sess *sess_by_sid(struct gw_line *gl, uint32_t sid)
{
	uint8_t ch = (uint8_t)(sid >> 16);

	if ((sid >> 24) != gl->idx || (sid & GW_SID_HOP) || ch >= gl->n_sess ||
	    gl->sess[ch].gen != (uint16_t)sid)
		return NULL;
	return &gl->sess[ch];
}

static void s_to_requester(void *ctx, const uint8_t d[8])
{
	struct gw_sess *s = ctx;

	if (s->answered_across && memcmp(d, s->across, 8) == 0) {
		s->answered_across = false; /* the lease sent it to the requester */
		return;
	}
	sdo_server_route_send(s->gl->node, s->ch, d);
}

static void s_to_target(void *ctx, const uint8_t d[8])
{
	struct gw_sess *s = ctx;
	gw_msg m = { .kind = M_TO_TARGET, .sid = sid_of(s), .channel = s->lease_ch };
	co_frame f;

	s->target_aborted = (d[0] >> 5) == SDO_CCS_ABORT;
	memcpy(m.d, d, 8);
	gw_relay_request_frame(&f, s->r.hop.node, d);
	if (gw_send_across(s->gl, s->target_line, &m, &f, &s->handoff_seq))
		GW_COUNT(s->gl->c.ring_drops); /* the session's timeout ends it */
}

static uint32_t s_open(void *ctx, const gw_hop *hop)
{
	struct gw_sess *s = ctx;
	static const uint8_t probe[8];
	uint32_t refuse;

	s->target_line = hop->line;
	/* whatever that line publishes for this session comes after */
	s->across_taken = atomic_load_explicit(&s->answer[hop->line].seq, memory_order_acquire);
	if (sdo_server_route_frame(s->gl->node, s->ch, probe, &s->reply) != 0)
		s->reply.id = 0;
	refuse = gw_lease_open(s->gl, hop, sid_of(s), &s->lease_ch, s->reply.id, s->reply.flags);
	/* Its frames go across only once the target line has bound the lease
	 * (the device's answer needs the lease's receive filter): once it has
	 * done this M_OPEN. */
	s->handoff_seq = s->gl->pushed_to[hop->line];
	return refuse;
}

static void s_close(void *ctx)
{
	struct gw_sess *s = ctx;

	gw_lease_close(s->gl, &s->r.hop, sid_of(s), s->lease_ch,
		       !s->lease_lost && !s->target_aborted);
}

static void s_done(void *ctx, uint32_t abort, gw_route_outcome o)
{
	struct gw_sess *s = ctx;
	struct gw_line *gl = s->gl;

	mbx_ev_gw_sdo ev = {
		.net = s->net,
		.node = s->r.target.node,
		.outcome = (uint8_t)o,
		.abort = abort,
		.target_line = s->r.opened || s->r.frames_to_target ? s->target_line : 0xFF,
		.router = s->r.hop.via_router ? s->r.hop.node : 0,
		.channel = s->ch,
		.frames = (uint32_t)(s->r.frames_to_target + s->r.frames_to_requester),
	};

	if (o == GW_OUT_REFUSED && !s->r.frames_to_target)
		ev.target_line = 0xFF;
	gw_route_count(&gl->routes, s->net, o);
	mbx_server_publish(line_mbx(gl->l), MBX_EV_GW_SDO, 0, &ev, sizeof ev);
	switch (o) {
	case GW_OUT_ROUTED:
		GW_COUNT(gl->c.routed);
		break;
	case GW_OUT_ABORTED:
		GW_COUNT(gl->c.aborted);
		break;
	case GW_OUT_TIMED_OUT:
		GW_COUNT(gl->c.timed_out);
		break;
	default:
		GW_COUNT(gl->c.refused);
		break;
	}
	sdo_server_route_end(gl->node, s->ch);
}

static const gw_sdo_route_ops sess_ops = {
	.to_requester = s_to_requester,
	.to_target = s_to_target,
	.open = s_open,
	.close = s_close,
	.done = s_done,
};

static uint32_t on_indication(void *ctx, uint8_t ch, const uint8_t d[8], uint64_t now_us)
{
	struct gw_line *gl = ctx;
	struct gw_sess *s;
	gw_netind ni;
	gw_hop hop = { 0 };
	uint32_t refuse;
	uint32_t target_ms = gl->p.sdo_timeout_ms;

	if (ch >= gl->n_sess)
		return GW_AB_ROUTE_BUSY;
	s = &gl->sess[ch];
	if (gw_sdo_route_busy(&s->r))
		return GW_AB_ROUTE_BUSY;
	GW_COUNT(gl->c.sessions);
	refuse = gw_netind_decode(d, &ni);
	if (!refuse)
		refuse = gw_route_resolve(&gl->routes, ni.net, ni.node, (int)gl->idx, &hop);
	/* A router answers only after its own target did: give it time for
	 * its own per-frame timeout first. */
	if (hop.via_router)
		target_ms *= 2;
	s->gen++;
	s->net = ni.net;
	s->lease_lost = s->target_aborted = false;
	s->started_us = now_us;
	gw_sdo_route_start(&s->r, ni, refuse, &hop, gl->p.sdo_timeout_ms, target_ms, now_us);
	return 0;
}

/* The target's answer, already sent to the requester by the target line. */
static void apply_answer_across(struct gw_sess *s, const uint8_t d[8], uint64_t now_us)
{
	s->answered_across = true;
	memcpy(s->across, d, 8);
	gw_sdo_route_target_frame(&s->r, d, now_us);
	s->answered_across = false;
}

/* The requester may already have the answer the target line sent across
 * and be answering it, while that line's message is still in the ring:
 * the session takes the answer from its record first, so that this frame
 * comes in turn (docs/gateway.md, "Frames across interfaces"). */
static void take_answer_across(struct gw_sess *s, uint64_t now_us)
{
	uint8_t d[8];

	if (s->r.opened && s->target_line < GW_LINES_MAX &&
	    gw_across_take(&s->answer[s->target_line], sid_of(s), &s->across_taken, d))
		apply_answer_across(s, d, now_us);
}

/* false: the answer taken first ended the session, so this frame is the
 * requester's next request to the server (e.g. a new network indication). */
static bool on_route_frame(void *ctx, uint8_t ch, const uint8_t d[8], uint64_t now_us)
{
	struct gw_line *gl = ctx;

	if (ch >= gl->n_sess)
		return true;
	take_answer_across(&gl->sess[ch], now_us);
	if (!gw_sdo_route_busy(&gl->sess[ch].r))
		return false;
	gw_sdo_route_requester_frame(&gl->sess[ch].r, d, now_us);
	return true;
}

static void on_route_ended(void *ctx, uint8_t ch)
{
	struct gw_line *gl = ctx;

	if (ch < gl->n_sess)
		gw_sdo_route_cancel(&gl->sess[ch].r, SDO_AB_GENERAL, line_loop_now_us(gl->l));
}

const sdo_server_route_ops gw_session_server_hook = {
	.indication = on_indication,
	.frame = on_route_frame,
	.ended = on_route_ended,
};

void gw_sessions_init(struct gw_line *gl)
{
	for (uint8_t i = 0; i < gl->n_sess; i++) {
		gl->sess[i].gl = gl;
		gl->sess[i].ch = i;
		gw_sdo_route_init(&gl->sess[i].r, &sess_ops, &gl->sess[i]);
	}
}

void gw_session_target_frame(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	struct gw_sess *s = sess_by_sid(gl, m->sid);

	if (!s)
		return;
	switch (m->sent) {
	case GW_SEND_FAILED:
		/* the session saw it in the message before, and may have
		 * ended on it: the channel need not be routed any more */
		if (s->reply.id) {
			memcpy(s->reply.data, m->d, 8);
			co_node_send(gl->node, &s->reply);
		}
		break;
	case GW_SENT_ACROSS:
		/* unless taken from the record already (take_answer_across) */
		if (gw_across_newer(&s->across_taken, m->across_seq))
			apply_answer_across(s, m->d, now_us);
		break;
	default:
		gw_sdo_route_target_frame(&s->r, m->d, now_us);
		break;
	}
}

void gw_session_lost(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	struct gw_sess *s = sess_by_sid(gl, m->sid);

	if (s) {
		s->lease_lost = true;
		gw_sdo_route_lost(&s->r, m->abort, now_us);
	}
}

uint64_t gw_sessions_tick(struct gw_line *gl, uint64_t now_us, uint64_t next)
{
	for (uint8_t i = 0; i < gl->n_sess; i++) {
		gw_sdo_route_tick(&gl->sess[i].r, now_us);
		if (gw_sdo_route_deadline(&gl->sess[i].r) < next)
			next = gw_sdo_route_deadline(&gl->sess[i].r);
	}
	return next;
}
