/* SPDX-License-Identifier: MIT */
/*
 * gateway/gw_relay.c - relay leases on the target line: one SDO client
 * channel of the line's pool lent to a routed session or a routed mailbox
 * transfer of any line, frames relayed both ways as messages. The
 * requester's line reserves the channel and the node on this line's
 * lending board (gateway/lend.h) and decides at once; this line binds the
 * lease when the reservation's M_OPEN reaches it (sdo_client_lease_channel)
 * and publishes what the reservation looks at: its link, its
 * heartbeat-lost nodes, and (through the gate of its SDO client pool) the
 * free channels and busy nodes. A lease whose requester vanished (its
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

/* The lease was taken by another line's transfer (its M_OPEN came before
 * the M_CLOSE: pending) and now parks for it, or ended: that M_OPEN is
 * carried out now - bound to the parked lease, or refused. */
static void relay_open_pending(struct gw_relay *r, uint64_t now_us)
{
	gw_msg m = r->pending;

	if (!r->has_pending)
		return;
	r->has_pending = false;
	gw_relay_open(r->gl, &m, now_us);
}

/* The channel back to the pool; the node's reservation is the caller's
 * (freed after it, then sdo_client_gate_kick: gw_lend_node_free). */
static void relay_unbind(struct gw_relay *r, uint64_t now_us)
{
	sdo_client_lease_end(r->gl->node, (uint8_t)r->cli_ch, now_us);
	r->used = false;
	r->orphaned = false;
	r->draining = false;
	r->parked = false;
	relay_open_pending(r, now_us);
}

/* The channel first, then the node (gw_lend_node_free). */
static void relay_free(struct gw_relay *r, uint64_t now_us)
{
	struct gw_line *gl = r->gl;
	uint8_t node = r->node;

	if (!r->used)
		return;
	relay_unbind(r, now_us);
	gw_lend_node_free(&gl->lend, node);
	sdo_client_gate_kick(gl->node, now_us);
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
	if (r->draining || r->parked)
		return; /* a late frame of the aborted transfer; none is due */
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
		if (!r->parked && gw_send_to(gl, r->from, &m))
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

/* Can this line carry frames now? Each look is published for the
 * reservations of other lines; one that sees a change from the last one
 * ends the leases it cut off, or frees them once it carries again. */
static void link_look(struct gw_line *gl, uint64_t now_us)
{
	bool carries = line_can_carry(gl->l);

	gl->link_events_seen = line_link_events(gl->l);
	gl->next_link_check_us = now_us + GW_LINK_CHECK_US;
	/* nothing is reserved while the leases it cut off are handled */
	if (!carries)
		gw_lend_set_carries(&gl->lend, false);
	if (carries != gl->carried) {
		gl->carried = carries;
		if (carries)
			relays_link_back(gl, now_us);
		else
			relays_link_lost(gl, GW_AB_NO_ANSWER);
	}
	if (carries)
		gw_lend_set_carries(&gl->lend, true);
}

/* The look costs two ioctls, so it is not made on every wake-up: at once
 * when the line saw a sign of change (a bus state change, a receive error
 * such as ENETDOWN), else at most every GW_LINK_CHECK_US. A lease toward a
 * line whose interface went down without such a sign (carrier lost) would
 * end only by the requester's per-frame timeout, and a line that is down
 * must be seen back: while leases are held or the line is down, the look
 * wakes the line every GW_LINK_CHECK_US (`forced`). */
static void relays_check_link(struct gw_line *gl, uint64_t now_us, bool forced, uint64_t *next)
{
	if (now_us >= gl->next_link_check_us || line_link_events(gl->l) != gl->link_events_seen)
		link_look(gl, now_us);
	if (forced && gl->next_link_check_us < *next)
		*next = gl->next_link_check_us;
}

/* A lease's slot is its client channel's: each message about it names
 * the channel (gw_msg.channel), so finding it is one look. */
static struct gw_relay *relay_slot(struct gw_line *gl, const gw_msg *m)
{
	return m->channel < GW_RELAYS_MAX ? &gl->relay[m->channel] : NULL;
}

/* The lease m (M_TO_TARGET, M_CLOSE) is about, serving its sender's sid. */
static struct gw_relay *relay_of(struct gw_line *gl, const gw_msg *m)
{
	struct gw_relay *r = relay_slot(gl, m);

	if (r && r->used && !r->orphaned && !r->draining && !r->parked && r->from == m->from &&
	    r->sid == m->sid)
		return r;
	return NULL;
}

/* ---- the lending board ------------------------------------------------------ */

void gw_lend_attach(struct gw_line *gl)
{
	gw_lend_init(&gl->lend);
	gw_lend_set_carries(&gl->lend, gl->carried);
	sdo_client_set_gate(gl->node, gw_lend_gate, &gl->lend); /* publishes the free channels */
}

void gw_lend_detach(struct gw_line *gl)
{
	gw_lend_set_carries(&gl->lend, false); /* nothing more is lent */
	sdo_client_set_gate(gl->node, NULL, NULL);
}

/* The next transfer of ours to line `to` (node) found every channel
 * held: take a lease of ours toward another node that ended well there
 * and is still offered (gw_lend_take_offer), node claimed for this
 * transfer. (One toward the same node gw_lend_reserve takes itself.)
 * 0 (m->channel, m->inherits set; *was_for: the node the lease was
 * toward) or GW_AB_NO_CLIENT. */
static uint32_t take_offered_channel(struct gw_line *gl, unsigned to, uint8_t node, gw_msg *m,
				     uint8_t *was_for)
{
	gw_lend *board = &gl->g->line[to].lend;

	for (unsigned i = 0; i < GW_CLOSING_MAX; i++) {
		struct gw_closing *c = &gl->closing[to][i];

		if (!c->node || c->node == node)
			continue;
		if (!gw_lend_claim_node(board, node))
			break; /* the node is busy too */
		if (gw_lend_take_offer(board, (uint8_t)gl->idx, c->node, c->channel, node)) {
			m->inherits = true;
			m->claimed_node = true;
			m->channel = c->channel;
			*was_for = c->node;
			c->node = 0;
			return 0;
		}
		gw_lend_give_back(board, GW_LEND_NONE, node);
		c->node = 0; /* the target ended it: gone */
	}
	return GW_AB_NO_CLIENT;
}

uint32_t gw_lease_open(struct gw_line *gl, const gw_hop *hop, uint32_t sid, uint8_t *channel,
		       uint32_t reply_id, uint8_t reply_flags)
{
	struct gw_line *tl = &gl->g->line[hop->line];
	gw_msg m = { .kind = M_OPEN,
		     .sid = sid,
		     .node = hop->node,
		     .reply_id = reply_id,
		     .reply_flags = reply_flags };
	int rc;
	uint8_t was_for = hop->node;
	uint32_t refuse = gw_lend_reserve(&tl->lend, (uint8_t)gl->idx, hop->node, &m.channel,
					  &m.inherits);

	/* The requester's next transfer right after its last one ended: that
	 * lease's channel (and node, if the same) are still held until the
	 * target takes its M_CLOSE, which the ring keeps ahead of this
	 * M_OPEN. Deciding on them now, they would look busy: the lease is
	 * taken over instead (the same node: gw_lend_reserve did). */
	if (refuse == GW_AB_NO_CLIENT)
		refuse = take_offered_channel(gl, hop->line, hop->node, &m, &was_for);
	if (refuse)
		return refuse;
	/* A mailbox hop's M_OPEN goes quietly: the target needs it only with
	 * the transfer's first frame, whose ordinary push wakes it and comes
	 * after it in the ring (or at any earlier wake-up: before_events);
	 * nothing of a TPDO waits for it: under the target's current
	 * publication. A session's wakes the target: it binds the lease while
	 * the requester takes the confirmation, so that the requester's first
	 * frame finds it bound and goes across (gw_send_across). */
	rc = reply_id ? gw_send_to(gl, hop->line, &m)
		      : gw_send_quiet_to(gl, hop->line, &m, gw_fast_epoch(&tl->fast));
	if (rc) {
		if (!m.inherits)
			gw_lend_give_back(&tl->lend, m.channel, hop->node);
		else if (gw_lend_untake(&tl->lend, (uint8_t)gl->idx, was_for, m.channel,
					hop->node) &&
			 m.claimed_node)
			gw_lend_give_back(&tl->lend, GW_LEND_NONE, hop->node);
		GW_COUNT(gl->c.ring_drops);
		return GW_AB_ROUTE_BUSY;
	}
	*channel = m.channel;
	return 0;
}
void gw_lease_close(struct gw_line *gl, const gw_hop *hop, uint32_t sid, uint8_t channel,
		    bool settled)
{
	gw_msg m = { .kind = M_CLOSE, .sid = sid, .channel = channel };
	unsigned to = hop->line;
	gw_lend *board = &gl->g->line[to].lend;

	if (settled)
		gw_lend_offer(board, (uint8_t)gl->idx, hop->node, channel);
	if (gw_send_to(gl, to, &m)) {
		if (settled)
			gw_lend_withdraw(board, (uint8_t)gl->idx, hop->node, channel);
		GW_COUNT(gl->c.ring_drops); /* the relay's idle limit frees it */
		return;
	}
	if (settled) {
		uint8_t i = gl->closing_next[to]++ % GW_CLOSING_MAX;
		gl->closing[to][i].node = hop->node;
		gl->closing[to][i].channel = channel;
	}
}

/* The parked lease of m's sender on m->channel toward m->node, or NULL
 * (none: the idle limit or a lost link freed it first). */
static struct gw_relay *parked_for(struct gw_line *gl, const gw_msg *m)
{
	struct gw_relay *r = relay_slot(gl, m);

	if (r && r->used && r->parked && r->from == m->from && r->node == m->node)
		return r;
	return NULL;
}

/* The lease still bound on m->channel that m's sender took over (its
 * offer was made before its M_CLOSE left), or NULL. */
static struct gw_relay *closing_for(struct gw_line *gl, const gw_msg *m)
{
	struct gw_relay *r = relay_slot(gl, m);

	if (r && r->used && !r->parked && !r->orphaned && !r->draining && !r->has_pending &&
	    r->from != m->from)
		return r;
	return NULL;
}

/* The lease bound on r's slot (channel r->cli_ch, now toward node) is
 * kept for line taker's M_OPEN (parked_for), and that M_OPEN carried out
 * if it came first. */
static void relay_keep(struct gw_relay *r, uint8_t node, uint8_t taker, uint64_t now_us)
{
	gw_msg pending = r->pending;
	bool has_pending = r->has_pending;

	*r = (struct gw_relay){ .used = true,
				.parked = true,
				.from = taker,
				.node = node,
				.cli_ch = r->cli_ch,
				.last_us = now_us,
				.has_pending = has_pending,
				.pending = pending,
				.gl = r->gl };
	relay_open_pending(r, now_us);
}

/* A lease that ended well, taken by its requester's line for the next
 * transfer (gw_lend_hand_over said so, and freed the old node if the
 * next one differs: the pool's requests waiting for it start at the
 * move): kept bound, moved to that transfer's node, for the M_OPEN behind
 * this M_CLOSE. If it cannot be moved, the channel goes back and that
 * M_OPEN finds nothing: it refuses and gives back the node its sender
 * claimed. */
static void relay_park(struct gw_relay *r, uint8_t next_node, uint8_t taker, uint64_t now_us)
{
	struct gw_line *gl = r->gl;

	if (next_node != r->node &&
	    sdo_client_lease_move(gl->node, (uint8_t)r->cli_ch, next_node, now_us) < 0) {
		relay_unbind(r, now_us);
		return;
	}
	relay_keep(r, next_node, taker, now_us);
}

/* A lease nobody took (yet) ends: the channel back first, then the node
 * freed and the offer withdrawn in one step (gw_lend_end_offered), so
 * that a transfer toward the node that finds it free finds the channel
 * free as well. One that took the offer in between gets the channel bound
 * again, kept for its M_OPEN as if it had come first; if something else
 * took the channel meanwhile, that M_OPEN finds nothing and refuses. */
static void relay_end_offered(struct gw_relay *r, uint64_t now_us)
{
	struct gw_line *gl = r->gl;
	uint8_t from = r->from, node = r->node, ch = (uint8_t)r->cli_ch, taker = 0, next;

	relay_unbind(r, now_us);
	next = gw_lend_end_offered(&gl->lend, from, node, ch, &taker);
	if (next && gw_lend_claim_channel(&gl->lend, ch)) {
		if (sdo_client_lease_channel(gl->node, ch, next, relay_rx, r, now_us) >= 0) {
			relay_keep(r, next, taker, now_us);
			return;
		}
		gw_lend_give_back(&gl->lend, ch, 0);
	}
	/* the same node stays held for the taker, whose M_OPEN finds nothing
	 * and does not free it; another node it claimed it gives back itself */
	if (next == node)
		gw_lend_node_free(&gl->lend, node);
	sdo_client_gate_kick(gl->node, now_us);
}

/* Bind the lease reserved for m->sid. The reservation was decided on what
 * this line published; what can refuse now is a change since then (the
 * link lost, the node's heartbeat lost, a parked lease freed), and the
 * requester's line hears it as M_LOST: its transfer ends with that abort
 * instead of hanging. */
void gw_relay_open(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	gw_msg lost = { .kind = M_LOST, .sid = m->sid };
	struct gw_relay *r = NULL;
	int ch = m->channel;

	if (m->inherits) {
		r = parked_for(gl, m);
		if (!r && (r = closing_for(gl, m))) {
			/* taken from another line's lease whose M_CLOSE (on that
			 * line's ring) has not come yet: when it comes */
			r->pending = *m;
			r->has_pending = true;
			return;
		}
	} else if ((r = relay_slot(gl, m)) && r->used) {
		r = NULL; /* the board and the leases disagree: refused */
	}
	if (!gl->carried || (r && r->orphaned) || gw_lend_is_silent(&gl->lend, m->node))
		lost.abort = GW_AB_NO_ANSWER;
	else if (!r)
		lost.abort = GW_AB_NO_CLIENT;
	else if (!m->inherits && (ch = sdo_client_lease_channel(gl->node, m->channel, m->node,
								relay_rx, r, now_us)) < 0)
		lost.abort = sdo_abort_of_errno(ch);
	if (lost.abort) {
		if (r && r->parked && !r->orphaned)
			relay_free(r, now_us); /* holds the channel and the node */
		else if (r && r->orphaned)
			; /* freed when the link is back (relays_link_back) */
		else if (!m->inherits)
			gw_lend_give_back(&gl->lend, m->channel, m->node);
		else if (m->claimed_node)
			gw_lend_node_free(&gl->lend, m->node);
		if (gw_send_to(gl, m->from, &lost))
			GW_COUNT(gl->c.ring_drops); /* the requester's timeout ends it */
		return;
	}
	*r = (struct gw_relay){ .used = true,
				.from = m->from,
				.sid = m->sid,
				.node = m->node,
				.cli_ch = ch,
				.last_us = now_us,
				/* nothing of this lease waits in the entry
				 * line's ring: its answers may go across */
				.reply_id = m->reply_id,
				.reply_flags = m->reply_flags,
				.gl = gl };
}

void gw_relay_to_target(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	struct gw_relay *r = relay_of(gl, m);
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
	struct gw_relay *r = relay_of(gl, m);
	uint8_t next_node, taker = 0;

	if (!r)
		return;
	if (r->engaged && r->aborted) {
		r->draining = true;
		r->last_us = now_us;
		relay_open_pending(r, now_us); /* nothing to take over */
		return;
	}
	next_node = gw_lend_hand_over(&gl->lend, r->from, r->node, (uint8_t)r->cli_ch, &taker);
	if (next_node)
		relay_park(r, next_node, taker, now_us);
	else
		relay_end_offered(r, now_us);
}

uint64_t gw_relays_tick(struct gw_line *gl, uint64_t now_us, uint64_t next)
{
	uint64_t idle = (uint64_t)gl->p.sdo_timeout_ms * 1000u * GW_RELAY_IDLE_FACTOR;
	bool held = false;
	uint64_t lost[2];

	/* a heartbeat is lost at a timer of this line: published in the same
	 * wake-up */
	co_hb_lost_nodes(gl->node, lost);
	gw_lend_set_silent(&gl->lend, lost);
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
	relays_check_link(gl, now_us, held || !gl->carried, &next);
	return next;
}
