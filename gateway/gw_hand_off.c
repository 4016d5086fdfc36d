/* SPDX-License-Identifier: MIT */
/*
 * gateway/gw_hand_off.c - the one way a gateway message leaves a line: the
 * ring to the other line (lines/xring.h: by value, single producer), or,
 * for the line itself, a small queue taken after the rings on its next
 * look, so that no message is ever handled inside the call that sent it
 * (a relayed SDO transfer sends from inside the SDO client); and the
 * frames of routed SDO transfers sent across to another line's bus.
 */
#include <errno.h>

#include "gateway/gw_line.h"
#include "lines/socketcan.h"

/* How the message wakes its line: at once; quietly (under `to`'s
 * publication epoch: gw_send_quiet_to); or right after the caller's next
 * step (gw_send_across: the frame first, then the wake-up). */
enum wake {
	WAKE_NOW,
	WAKE_QUIET,
	WAKE_LATER
};

static int hand_off(struct gw_line *gl, unsigned to, gw_msg *m, enum wake wake, uint32_t epoch)
{
	bool quiet = wake == WAKE_QUIET;

	m->from = (uint8_t)gl->idx;
	if (to == gl->idx) {
		if (gl->self_len == GW_SELF_SLOTS)
			return -ENOBUFS;
		gl->self[(gl->self_head + gl->self_len++) % GW_SELF_SLOTS] = *m;
		return 0;
	}
	xring *r = xring_mesh_get(gl->g->mesh, gl->idx, to);
	bool all_done = quiet && atomic_load_explicit(&gl->g->line[to].done_from[gl->idx],
						      memory_order_acquire) == gl->pushed_to[to];
	int rc = !r                   ? -EINVAL
		 : quiet              ? xring_push_quiet(r, m, sizeof(*m), GW_QUIET_WAKE_AT)
		 : wake == WAKE_LATER ? xring_push_wake_later(r, m, sizeof(*m))
				      : xring_push(r, m, sizeof(*m));

	if (rc)
		return rc;
	gl->pushed_to[to]++;
	if (!quiet)
		gl->woken_mark[to] = gl->pushed_to[to];
	else if (all_done)
		gl->quiet_epoch[to] = epoch; /* the first one `to` has not done */
	return 0;
}

/* Why the message goes first: the owner takes its rings at the start of
 * each wake-up (line_ext.h before_events), so the one the answer to this
 * frame causes normally finds the message taken; where it does not (the
 * message came while the owner was already awake), the owner copes: a
 * lease hands such an answer to the session instead of sending it across
 * (gw_relay.c), a session takes an answer sent across from its record
 * (gw_across_take) before the requester's next frame.
 * Why the wait for *handoff_seq: a frame handed off earlier may still be
 * in the ring or the owner's transmit queue, and this one must not
 * overtake it. */
bool gw_may_send_across(const struct gw_line *gl, unsigned to, uint64_t handoff_seq)
{
	return to != gl->idx && gl->g->line[to].peer_fd[gl->idx] >= 0 &&
	       atomic_load_explicit(&gl->g->line[to].done_from[gl->idx], memory_order_acquire) >=
		       handoff_seq;
}

int gw_send_across(struct gw_line *gl, unsigned to, gw_msg *m, const co_frame *f,
		   uint64_t *handoff_seq)
{
	int rc;

	m->sent = GW_OWNER_SENDS;
	if (f && gw_may_send_across(gl, to, *handoff_seq)) {
		m->sent = GW_SENT_ACROSS;
		/* the message before the frame, the owner's wake-up after it:
		 * the frame does not wait for that system call */
		if ((rc = hand_off(gl, to, m, WAKE_LATER, 0)))
			return rc;
		rc = can_tx_socket_send(gl->g->line[to].peer_fd[gl->idx], f);
		xring_wake(xring_mesh_get(gl->g->mesh, gl->idx, to));
		if (rc == 0) {
			GW_COUNT(gl->c.sdo_across);
			return 0;
		}
		m->sent = GW_SEND_FAILED; /* congested or down: the owner tries */
	}
	if ((rc = gw_send_to(gl, to, m)))
		return rc;
	*handoff_seq = gl->pushed_to[to];
	return 0;
}

uint32_t gw_across_publish(struct gw_across *a, uint32_t sid, const uint8_t d[8])
{
	uint32_t seq = atomic_load_explicit(&a->seq, memory_order_relaxed);

	atomic_store_explicit(&a->seq, seq + 1, memory_order_relaxed);
	atomic_thread_fence(memory_order_release);
	atomic_store_explicit(&a->sid, sid, memory_order_relaxed);
	atomic_store_explicit(&a->d, co_get_le(d, 8), memory_order_relaxed);
	atomic_store_explicit(&a->seq, seq + 2, memory_order_release);
	return seq + 2;
}

bool gw_across_take(const struct gw_across *a, uint32_t sid, uint32_t *taken, uint8_t d[8])
{
	uint32_t seq = atomic_load_explicit(&a->seq, memory_order_acquire);
	uint32_t got_sid = atomic_load_explicit(&a->sid, memory_order_relaxed);
	uint64_t bytes = atomic_load_explicit(&a->d, memory_order_relaxed);

	atomic_thread_fence(memory_order_acquire);
	if ((seq & 1u) || atomic_load_explicit(&a->seq, memory_order_relaxed) != seq ||
	    got_sid != sid || !gw_across_newer(taken, seq))
		return false;
	co_put_le(d, 8, bytes);
	return true;
}

bool gw_across_newer(uint32_t *taken, uint32_t seq)
{
	if ((int32_t)(seq - *taken) <= 0)
		return false;
	*taken = seq;
	return true;
}

int gw_send_to(struct gw_line *gl, unsigned to, gw_msg *m)
{
	return hand_off(gl, to, m, WAKE_NOW, 0);
}

int gw_send_quiet_to(struct gw_line *gl, unsigned to, gw_msg *m, uint32_t epoch)
{
	return hand_off(gl, to, m, WAKE_QUIET, epoch);
}

int gw_send_by_loop_end(struct gw_line *gl, unsigned to, gw_msg *m)
{
	int rc = hand_off(gl, to, m, WAKE_LATER, 0); /* to itself: its own queue */

	if (!rc && to != gl->idx)
		gl->owed_wake |= UINT32_C(1) << to;
	return rc;
}

void gw_wake_owed(struct gw_line *gl)
{
	for (uint32_t owed = gl->owed_wake; owed; owed &= owed - 1)
		xring_wake(xring_mesh_get(gl->g->mesh, gl->idx, (unsigned)__builtin_ctz(owed)));
	gl->owed_wake = 0;
}

bool gw_may_send_fast(const struct gw_line *gl, unsigned to, uint32_t epoch)
{
	uint64_t done = atomic_load_explicit(&gl->g->line[to].done_from[gl->idx],
					     memory_order_acquire);

	if (done == gl->pushed_to[to])
		return true;
	/* A target that does not take its messages (stalled, or behind by
	 * as many as wake it) gets its frames back: it must not fall behind
	 * what the bus shows without bound. */
	return gl->pushed_to[to] - done < GW_QUIET_WAKE_AT && done >= gl->woken_mark[to] &&
	       epoch == gl->quiet_epoch[to];
}

void gw_publish_done(struct gw_line *gl)
{
	if (!line_tx_idle(gl->l))
		return; /* a frame of a handled message may still be queued */
	for (unsigned i = 0; i < gl->g->n; i++)
		if (atomic_load_explicit(&gl->done_from[i], memory_order_relaxed) !=
		    gl->handled_from[i])
			atomic_store_explicit(&gl->done_from[i], gl->handled_from[i],
					      memory_order_release);
}

bool gw_self_take(struct gw_line *gl, gw_msg *out)
{
	if (!gl->self_len)
		return false;
	*out = gl->self[gl->self_head];
	gl->self_head = (uint16_t)((gl->self_head + 1) % GW_SELF_SLOTS);
	gl->self_len--;
	return true;
}
