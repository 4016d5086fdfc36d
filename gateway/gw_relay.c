/* SPDX-License-Identifier: MIT */
/*
 * gateway/gw_relay.c - relay leases on the target line: one SDO client
 * channel of the line's pool lent (core/sdo_client.h sdo_client_lease) to
 * a routed session or a routed mailbox transfer of any line, frames
 * relayed both ways as messages. A lease whose requester vanished (its
 * CLOSE lost to a full ring) is given back after an idle limit, so every
 * channel is released whatever happens; a line that stops carrying frames
 * ends its requesters at once; a lease whose requester aborted stays until
 * the device is quiet (docs/gateway.md). The session's frames for the
 * device usually come already sent (gw_send_across): the message only
 * keeps the lease's state; the device's one answer to a request of a
 * normal transfer goes across to the requester the same way.
 */
#include <errno.h>
#include <string.h>

#include "core/heartbeat.h"
#include "core/sdo_client.h"
#include "gateway/convention.h"
#include "gateway/gw_line.h"

static void relay_free(struct gw_relay *r, uint64_t now_us)
{
	if (!r->used)
		return;
	sdo_client_lease_end(r->gl->node, (uint8_t)r->cli_ch, now_us);
	r->used = false;
	r->orphaned = false;
	r->draining = false;
}

void gw_relay_request_frame(co_frame *f, uint8_t node, const uint8_t d[8])
{
	co_frame_init(f, SDO_COB_RX_BASE + node, 8);
	memcpy(f->data, d, 8);
}

/* Where the session this lease serves looks for an answer sent across
 * (the session's record for this line), or NULL. */
static struct gw_across *answer_record(const struct gw_relay *r)
{
	const struct gw_line *entry = &r->gl->g->line[r->from];
	uint8_t ch = (uint8_t)((r->sid >> 16) & 0x7Fu);

	if ((r->sid & GW_SID_HOP) || ch >= entry->n_sess)
		return NULL;
	return &entry->sess[ch].answer[r->gl->idx];
}

/* The device's frame goes across to the requester only when it is the one
 * answer due to the requester's last frame and one the session forwards
 * unchanged (gw_sdo_route_answer_passes): anything else - a second frame,
 * block transfers, a wrong answer, an answer to a request whose message
 * has not come yet - is handed to the session, which decides as before. */
static void relay_rx(void *arg, const uint8_t d[8], uint64_t now_us)
{
	struct gw_relay *r = arg;
	gw_msg m = { .kind = M_TO_REQ, .sid = r->sid };
	struct gw_across *rec = NULL;
	co_frame f;
	bool across;

	r->last_us = now_us;
	if (r->draining)
		return; /* a late frame of the aborted transfer */
	memcpy(m.d, d, 8);
	GW_COUNT(r->gl->c.relayed_frames);
	if (r->reply_id && !r->block && !r->asked_valid && r->answers_early < UINT8_MAX)
		r->answers_early++;
	/* the record only for an answer that does go across */
	across = r->reply_id && r->asked_valid && gw_sdo_route_answer_passes(r->asked, d) &&
		 gw_may_send_across(r->gl, r->from, r->handoff_seq) && (rec = answer_record(r));
	r->asked_valid = false;
	if (across) {
		co_frame_init(&f, r->reply_id, 8);
		f.flags = r->reply_flags;
		memcpy(f.data, d, 8);
		m.across_seq = gw_across_publish(rec, r->sid, d);
	}
	if (gw_send_across(r->gl, r->from, &m, across ? &f : NULL, &r->handoff_seq))
		GW_COUNT(r->gl->c.ring_drops);
}

/* This line's link went down: tell each requester's line, so that its
 * session ends now with `abort`; the leases stay, orphaned, until the
 * device can be told as well (relays_link_back). */
static void relays_link_lost(struct gw_line *gl, uint32_t abort)
{
	for (unsigned i = 0; i < GW_RELAYS_MAX; i++) {
		struct gw_relay *r = &gl->relay[i];
		gw_msg m = { .kind = M_LOST, .sid = r->sid, .abort = abort };

		if (!r->used || r->orphaned || r->draining)
			continue;
		if (gw_send_to(gl, r->from, &m))
			GW_COUNT(gl->c.ring_drops); /* the requester's timeout ends it */
		r->orphaned = true;
	}
}

/* The link is back: a device left in the middle of an orphaned transfer
 * gets an abort (else it would refuse the next request toward it until
 * its own timeout, if it has one), and the channel is free again. */
static void relays_link_back(struct gw_line *gl, uint64_t now_us)
{
	for (unsigned i = 0; i < GW_RELAYS_MAX; i++) {
		struct gw_relay *r = &gl->relay[i];
		uint8_t d[8];

		if (!r->used || !r->orphaned)
			continue;
		if (r->engaged) {
			gw_sdo_abort_encode(d, r->mux, SDO_AB_GENERAL);
			sdo_client_lease_send(gl->node, (uint8_t)r->cli_ch, d);
		}
		relay_free(r, now_us);
	}
}

/* Can this line carry frames now? Each look that sees a change from the
 * last one ends the leases it cut off, or frees them once it carries
 * again - whichever look saw it (the periodic check or a lease request). */
static bool link_look(struct gw_line *gl, uint64_t now_us)
{
	bool carries = line_can_carry(gl->l);

	if (carries != gl->carried) {
		gl->carried = carries;
		if (carries)
			relays_link_back(gl, now_us);
		else
			relays_link_lost(gl, GW_AB_NO_ANSWER);
	}
	return carries;
}

/* A lease toward a line whose interface went down (ip link set down,
 * carrier lost) or bus-off would otherwise end only by the requester's
 * per-frame timeout: while leases are held (the caller knows), look at
 * the line every GW_LINK_CHECK_US. */
static void relays_check_link(struct gw_line *gl, uint64_t now_us, uint64_t *next)
{
	if (now_us >= gl->next_link_check_us) {
		gl->next_link_check_us = now_us + GW_LINK_CHECK_US;
		link_look(gl, now_us);
	}
	if (gl->next_link_check_us < *next)
		*next = gl->next_link_check_us;
}

static struct gw_relay *relay_by_sid(struct gw_line *gl, uint8_t from, uint32_t sid)
{
	for (unsigned i = 0; i < GW_RELAYS_MAX; i++)
		if (gl->relay[i].used && !gl->relay[i].orphaned && !gl->relay[i].draining &&
		    gl->relay[i].from == from && gl->relay[i].sid == sid)
			return &gl->relay[i];
	return NULL;
}

/* Can this line serve a lease toward node now? 0 or the refusal. */
static uint32_t relay_check(struct gw_line *gl, uint8_t node, uint64_t now_us)
{
	if (!link_look(gl, now_us))
		return GW_AB_NO_ANSWER;
	if (co_hb_consumer_status(gl->node, node) == CO_HB_MON_LOST)
		return GW_AB_NO_ANSWER; /* known silent: refuse now, not by a timeout */
	return 0;
}

void gw_relay_open(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	gw_msg ans = { .kind = M_OPENED, .sid = m->sid };
	struct gw_relay *r = NULL;
	int ch;

	ans.abort = relay_check(gl, m->node, now_us);
	for (unsigned i = 0; !ans.abort && i < GW_RELAYS_MAX && !r; i++)
		if (!gl->relay[i].used)
			r = &gl->relay[i];
	if (!ans.abort && !r)
		ans.abort = GW_AB_NO_CLIENT;
	if (!ans.abort) {
		ch = sdo_client_lease(gl->node, m->node, 0, 0, relay_rx, r, now_us);
		if (ch >= 0) {
			r->used = true;
			r->orphaned = false;
			r->from = m->from;
			r->sid = m->sid;
			r->cli_ch = ch;
			r->engaged = false;
			r->aborted = false;
			r->draining = false;
			r->last_us = now_us;
			r->reply_id = m->reply_id;
			r->reply_flags = m->reply_flags;
			r->asked_valid = false;
			r->answers_early = 0;
			r->block = false;
			/* its answers come after the session's M_OPENED (the
			 * same ring, in order) */
			r->handoff_seq = 0;
		} else {
			ans.abort = sdo_abort_of_errno(ch);
		}
	}
	if (gw_send_to(gl, m->from, &ans)) {
		GW_COUNT(gl->c.ring_drops);
		if (r && r->used)
			relay_free(r, now_us);
	}
}

void gw_relay_to_target(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	struct gw_relay *r = relay_by_sid(gl, m->from, m->sid);
	uint8_t cs = m->d[0] >> 5;

	if (!r)
		return;
	if (m->sent == GW_SEND_FAILED) { /* its message came before */
		sdo_client_lease_send(gl->node, (uint8_t)r->cli_ch, m->d);
		return;
	}
	if (!r->engaged)
		memcpy(r->mux, &m->d[1], sizeof r->mux);
	r->engaged = true;
	r->aborted = cs == SDO_CCS_ABORT;
	r->last_us = now_us;
	r->block |= cs == SDO_CCS_BLK_DN || cs == SDO_CCS_BLK_UP;
	r->asked = m->d[0];
	if (m->sent == GW_OWNER_SENDS) {
		r->answers_early = 0; /* the device's answer comes after this */
		r->asked_valid = !r->block;
	} else if (r->answers_early) {
		r->answers_early--; /* sent across and answered before we knew */
		r->asked_valid = false;
	} else {
		r->asked_valid = !r->block;
	}
	GW_COUNT(gl->c.relayed_frames);
	if (m->sent == GW_OWNER_SENDS)
		sdo_client_lease_send(gl->node, (uint8_t)r->cli_ch, m->d);
}

void gw_relay_close(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	struct gw_relay *r = relay_by_sid(gl, m->from, m->sid);

	if (!r)
		return;
	if (r->engaged && r->aborted) {
		r->draining = true;
		r->last_us = now_us;
		return;
	}
	relay_free(r, now_us);
}

uint64_t gw_relays_tick(struct gw_line *gl, uint64_t now_us, uint64_t next)
{
	uint64_t idle = (uint64_t)gl->p.sdo_timeout_ms * 1000u * GW_RELAY_IDLE_FACTOR;
	bool held = false;

	for (unsigned i = 0; i < GW_RELAYS_MAX; i++) {
		struct gw_relay *r = &gl->relay[i];
		if (!r->used)
			continue;
		uint64_t limit = r->draining ? GW_DRAIN_US : idle;
		if (now_us - r->last_us >= limit) {
			relay_free(r, now_us);
			continue;
		}
		held = true;
		if (r->last_us + limit < next)
			next = r->last_us + limit;
	}
	if (held)
		relays_check_link(gl, now_us, &next);
	return next;
}
