/* SPDX-License-Identifier: MIT */
/*
 * gateway/gw_hand_off.c - the one way a gateway message leaves a line: the
 * ring to the other line (lines/xring.h: by value, single producer), or,
 * for the line itself, a small queue taken after the rings on its next
 * look, so that no message is ever handled inside the call that sent it
 * (a relayed SDO transfer sends from inside the SDO client).
 */
#include <errno.h>

#include "gateway/gw_line.h"

/* quiet: a quiet message sent under `to`'s publication epoch. */
static int hand_off(struct gw_line *gl, unsigned to, gw_msg *m, bool quiet, uint32_t epoch)
{
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
	int rc = !r      ? -EINVAL
		 : quiet ? xring_push_quiet(r, m, sizeof(*m), GW_QUIET_WAKE_AT)
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

int gw_send_to(struct gw_line *gl, unsigned to, gw_msg *m)
{
	return hand_off(gl, to, m, false, 0);
}

int gw_send_quiet_to(struct gw_line *gl, unsigned to, gw_msg *m, uint32_t epoch)
{
	return hand_off(gl, to, m, true, epoch);
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
