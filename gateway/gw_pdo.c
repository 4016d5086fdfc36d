/* SPDX-License-Identifier: MIT */
/*
 * gateway/gw_pdo.c - PDO forwarding at run time: a B-object written on this
 * line goes into the shared image (gateway/image.h) and, as a message, to
 * every line whose TPDOs map it; an update from another line is applied to
 * this line's OD and triggers its TPDOs; after a drop, the image's latest
 * value (gateway/pdo_sync.h). An event-driven TPDO of another line that
 * may go now is sent by this line's thread itself, on its socket on that
 * line's interface (gateway/fast_tpdo.h); the message still carries the
 * value, and says so.
 */
#include <string.h>

#include "core/od.h"
#include "core/pdo.h"
#include "gateway/gw_line.h"
#include "lines/socketcan.h"

static int fast_send(void *ctx, const co_frame *f)
{
	return can_tx_socket_send(*(const int *)ctx, f);
}

/* Hand slot's update to line j: its TPDOs that may go now leave from here,
 * the message tells j which ones did. When they all did and nothing else
 * on j acts on the value, j is not woken for it: it applies the value at
 * its next wake-up, before anything else it does then (its timers, a
 * request, a frame), so nobody sees the difference but j's thread, which
 * sleeps through it. Else j is woken at the end of this loop iteration,
 * with the other updates of the same frame (gw_send_by_loop_end). 0 or
 * the hand-off's -errno. */
static int forward_to(struct gw_line *gl, unsigned j, gw_msg *m, uint64_t now_us)
{
	struct gw_line *tl = &gl->g->line[j];
	bool quiet = false;
	uint32_t epoch = 0;
	int rc;

	m->fast_sent = 0;
	m->fast_held = 0;
	m->n_fast = 0;
	m->sent_us = now_us;
	/* A message of ours not yet done by the target (queued, being
	 * handled, or its frame still in the target's transmit queue): the
	 * target is behind and keeps the hand-off until it caught up, so no
	 * frame of ours overtakes one it sends for an earlier value (quiet
	 * ones aside: gw_may_send_fast). Held either way. */
	if (tl->peer_fd[gl->idx] >= 0) {
		epoch = gw_fast_epoch(&tl->fast);
		if (gw_may_send_fast(gl, j, epoch))
			m->fast_sent = gw_fast_try(&tl->fast, gl->g->img, m->slot, now_us,
						   fast_send, &tl->peer_fd[gl->idx], &m->fast_held,
						   m->fast_nr);
		else
			m->fast_held = gw_fast_tpdos_of(&tl->fast, m->slot);
		gw_fast_hold(&tl->fast, m->fast_held);
		m->n_fast = (uint8_t)__builtin_popcount(m->fast_sent);
		quiet = m->fast_sent && !m->fast_held && gw_fast_quiet_ok(&tl->fast, m->slot);
	}
	for (uint32_t k = m->fast_sent; k; k &= k - 1)
		GW_COUNT(gl->c.pdo_fast);
	rc = quiet ? gw_send_quiet_to(gl, j, m, epoch) : gw_send_by_loop_end(gl, j, m);
	if (rc)
		gw_fast_undo_hold(&tl->fast, m->fast_held);
	return rc;
}

/* A B-object of this line's OD was written - by an RPDO, over SDO or by a
 * mailbox client (its after_write hook): into the shared image, and to
 * every other line whose TPDOs map it. */
static void image_written(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct gw_line *gl = ctx;
	gw *g = gl->g;
	int slot;
	gw_msg m = { .kind = M_FWD };

	if (a->origin == CO_OD_ORIGIN_RESET)
		return; /* defaults restored on this line only */
	slot = gw_image_find(g->img, e->index, e->sub);
	if (slot < 0)
		return;
	m.bits = gw_image_bits_from(e->data, (uint8_t)e->size);
	gw_image_write(g->img, slot, m.bits);
	GW_COUNT(gl->c.pdo_published);
	m.slot = (uint16_t)slot;
	for (unsigned j = 0; j < g->n; j++) {
		if (j == gl->idx || !gw_fwd_list_has(&g->line[j].fwd, slot))
			continue;
		if (forward_to(gl, j, &m, line_loop_now_us(gl->l))) {
			GW_COUNT(gl->c.pdo_dropped);
			gw_pdo_sync_mark(&g->line[j].lost, slot);
		} else {
			GW_COUNT(gl->c.pdo_forwarded);
		}
	}
}

const co_od_hooks gw_image_hooks = {
	.after_write = image_written,
};

/* only_if_changed: a resync, which must not trigger a TPDO for a value
 * this line already holds. Returns whether the value was stored. */
static bool pdo_apply(struct gw_line *gl, int slot, uint64_t bits, bool only_if_changed,
		      uint64_t now_us)
{
	const gw_image_slot *s = gw_image_slot_at(gl->g->img, slot);
	uint8_t buf[8];
	co_od_entry *e;

	if (!s || !(e = co_od_find(co_node_od(gl->node), s->index, s->sub)))
		return false;
	gw_image_bits_to(bits, buf, s->size);
	if (only_if_changed && e->size == s->size && memcmp(e->data, buf, s->size) == 0)
		return false;
	/* The store runs no hook: the update does not come back as ours. */
	if (co_od_entry_set_bytes(e, buf, s->size))
		return false;
	GW_COUNT(gl->c.pdo_applied);
	if (co_pdo_object_changed(gl->node, s->index, s->sub, now_us) > 0)
		GW_COUNT(gl->c.pdo_triggered);
	/* for the line's other extensions: the device object layer forwards
	 * it to a device (gateway.forward) */
	co_event ev = {
		.kind = CO_EV_OBJECT_UPDATED,
		.now_us = now_us,
		.u.pdo_obj = { .index = s->index, .sub = s->sub, .bits = (uint8_t)(s->size * 8u) }
	};
	co_node_emit(gl->node, &ev);
	return true;
}

/* An update from another line, in the order its source wrote them. The
 * TPDOs the source already sent for it have their inhibit and event
 * timers restarted from that transmission and are not sent again (the
 * gate answers SERVED while the value is applied). */
void gw_pdo_received(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	for (uint8_t i = 0; i < m->n_fast && i < GW_FAST_SENT_MAX; i++)
		(void)co_pdo_tpdo_sent_by_peer(gl->node, m->fast_nr[i], m->sent_us);
	gl->fast.serving_nr = m->fast_nr;
	gl->fast.n_serving = m->n_fast < GW_FAST_SENT_MAX ? m->n_fast : GW_FAST_SENT_MAX;
	pdo_apply(gl, m->slot, m->bits, false, now_us);
	gl->fast.n_serving = 0;
	gw_fast_taken(&gl->fast, m->fast_held, line_tx_idle(gl->l));
	gw_pdo_sync_received(&gl->lost, gl->g->img, m->slot, m->bits);
}

/* gw_pdo_sync_apply_fn: a resync, which must not trigger a TPDO for a
 * value this line already holds. */
bool gw_pdo_resync_apply(void *ctx, int slot, uint64_t bits)
{
	struct gw_line *gl = ctx;

	return pdo_apply(gl, slot, bits, true, line_loop_now_us(gl->l));
}

/* ---- the fast path of this line's TPDOs (gateway/fast_tpdo.h) ---------------- */

int gw_fast_attach(struct gw_line *gl)
{
	int rc = gw_fast_init(&gl->fast, gw_image_count(gl->g->img));

	if (rc)
		return rc;
	co_pdo_set_tx_gate(gl->node, gw_fast_gate, &gl->fast);
	gw_fast_refresh(gl);
	return 0;
}

void gw_fast_detach(struct gw_line *gl)
{
	co_pdo_set_tx_gate(gl->node, NULL, NULL);
	gw_fast_fini(&gl->fast);
}

/* The image slot of this line's object index:sub when it is a B-object
 * with no hook but the gateway's (a read hook could refresh the value on
 * this thread only), else -1. */
static int image_slot_of(struct gw_line *gl, uint16_t index, uint8_t sub)
{
	int slot = gw_image_find(gl->g->img, index, sub);
	co_od_entry *e = co_od_find(co_node_od(gl->node), index, sub);

	return slot >= 0 && e && e->hooks == &gw_image_hooks && e->hook_ctx == gl ? slot : -1;
}

/* The frame of TPDO nr from its mapping: every object a B-object. */
static bool map_from_od(struct gw_line *gl, uint16_t nr, gw_fast_desc *d)
{
	co_od *od = co_node_od(gl->node);
	uint16_t map = (uint16_t)(CO_PDO_TPDO_MAP + nr - 1);
	uint32_t entry;
	uint8_t count;

	if (co_od_get_u8(od, map, 0, &count) || count == 0 || count > CO_PDO_MAX_MAP)
		return false;
	for (uint8_t i = 1; i <= count; i++) {
		int slot;

		if (co_od_get_u32(od, map, i, &entry))
			return false;
		slot = image_slot_of(gl, (uint16_t)(entry >> 16), (uint8_t)(entry >> 8));
		if (slot < 0)
			return false;
		d->map[i - 1] = (uint32_t)slot << 8 | (entry & 0xFFu);
	}
	d->n = count;
	d->fit = 0;
	return true;
}

/* The frame of TPDO nr from the objects another extension named for it
 * (line_tpdo_sources: a device object's RPDO, devobj/forward.c): every
 * one a B-object, each value to fit its bits, the frame no longer than
 * the TPDO's. */
static bool map_from_sources(struct gw_line *gl, uint16_t nr, uint8_t len, gw_fast_desc *d)
{
	const line_tpdo_source *src;
	uint8_t n = line_tpdo_sources_get(gl->l, nr, &src);
	unsigned bits = 0;

	if (n == 0 || n > CO_PDO_MAX_MAP)
		return false;
	for (uint8_t i = 0; i < n; i++) {
		int slot = image_slot_of(gl, src[i].index, src[i].sub);

		bits += src[i].bits;
		if (slot < 0 || bits > 8u * len)
			return false;
		d->map[i] = (uint32_t)slot << 8 | src[i].bits |
			    (src[i].is_signed ? GW_FAST_MAP_SIGNED : 0u);
	}
	d->n = n;
	d->fit = 1;
	return true;
}

/* Valid TPDO nr (state st) is one another thread may send: event-driven,
 * the node OPERATIONAL, and its frame made of B-objects of the image. */
static bool fast_desc(struct gw_line *gl, uint16_t nr, const co_pdo_tpdo_state *st, gw_fast_desc *d)
{
	uint32_t id;
	uint8_t flags;

	if (!st->operational || st->tt < CO_PDO_TT_EVENT_MANUF || st->len == 0 || st->len > 8)
		return false;
	if (!map_from_od(gl, nr, d) && !map_from_sources(gl, nr, st->len, d))
		return false;
	co_cob_split(st->cob_id, &id, &flags);
	d->nr = nr;
	d->can_id = id;
	d->flags = flags;
	d->len = st->len;
	d->inhibit_us = (uint32_t)st->inhibit_100us * 100u;
	return true;
}

/* Frames other lines send for our fast TPDOs reach this line's socket
 * too: it would wake for each one only to drop it (a data frame on one of
 * its own TPDO COB-IDs). Its port leaves them out, as it leaves out what it
 * sends itself; only when the set changes. */
_Static_assert(GW_FAST_MAX <= CAN_PORT_IGNORE_MAX, "every fast TPDO can be left out");

static void ignore_fast_frames(struct gw_line *gl, const gw_fast_desc *d, unsigned n)
{
	co_frame ids[GW_FAST_MAX];
	bool any_sender = false;

	for (unsigned i = 0; i < GW_LINES_MAX; i++)
		any_sender |= gl->peer_fd[i] >= 0;
	if (!any_sender)
		n = 0;
	for (unsigned i = 0; i < n; i++) {
		memset(&ids[i], 0, sizeof(ids[i]));
		ids[i].id = d[i].can_id;
		ids[i].flags = d[i].flags;
	}
	if (n == gl->n_ignored && memcmp(ids, gl->ignored, n * sizeof(ids[0])) == 0)
		return;
	if (line_ignore_own_tpdos(gl->l, ids, n) == 0) {
		memcpy(gl->ignored, ids, n * sizeof(ids[0]));
		gl->n_ignored = n;
	}
}

static void mark_slot(uint64_t *words, size_t n_words, int slot)
{
	if (slot >= 0 && (size_t)slot / 64 < n_words)
		words[slot / 64] |= UINT64_C(1) << (slot % 64);
}

/* The image slots TPDO nr maps into words (bit per slot). */
static void mark_mapped_slots(struct gw_line *gl, uint16_t nr, uint64_t *words, size_t n_words)
{
	co_od *od = co_node_od(gl->node);
	uint16_t map = (uint16_t)(CO_PDO_TPDO_MAP + nr - 1);
	uint32_t entry;
	uint8_t count;

	if (co_od_get_u8(od, map, 0, &count))
		return;
	for (uint8_t i = 1; i <= count && i <= CO_PDO_MAX_MAP; i++) {
		int slot;

		if (co_od_get_u32(od, map, i, &entry))
			continue;
		slot = gw_image_find(gl->g->img, (uint16_t)(entry >> 16), (uint8_t)(entry >> 8));
		mark_slot(words, n_words, slot);
	}
}

/* One look at every TPDO: the fast ones (at most GW_FAST_MAX), and the
 * quiet set (gateway/fast_tpdo.h): the slots that only fast TPDOs map and
 * that no other part of this line acts on (a device object forwarded from
 * it is pinned, gateway.forward: its device's RPDO waits for the value). */
void gw_fast_refresh(struct gw_line *gl)
{
	gw_fast *F = &gl->fast;
	size_t words = F->quiet_words;
	uint64_t until[GW_FAST_MAX];
	bool pending[GW_FAST_MAX];
	unsigned n = 0;
	co_pdo_tpdo_state st;

	if (!F->by_slot)
		return;
	memset(F->quiet_next, 0, words * sizeof(*F->quiet_next));
	memset(F->mapped_slow, 0, words * sizeof(*F->mapped_slow));
	memset(F->sourced, 0, words * sizeof(*F->sourced));
	for (uint16_t nr = 1; nr <= CO_PDO_MAX; nr++) {
		if (co_pdo_tpdo_state_get(gl->node, nr, &st) || !st.valid)
			continue;
		if (n == GW_FAST_MAX || !fast_desc(gl, nr, &st, &F->next[n])) {
			mark_mapped_slots(gl, nr, F->mapped_slow, words);
			continue;
		}
		for (uint8_t i = 0; i < F->next[n].n; i++) {
			mark_slot(F->quiet_next, words, (int)(F->next[n].map[i] >> 8));
			if (F->next[n].fit)
				mark_slot(F->sourced, words, (int)(F->next[n].map[i] >> 8));
		}
		until[n] = st.inhibit_until;
		pending[n] = st.event_pending;
		n++;
	}
	for (size_t w = 0; w < words; w++) {
		uint64_t pinned = gl->fwd.pinned && w < gl->fwd.words ? gl->fwd.pinned[w] : 0;
		/* a forward whose device RPDO is a fast TPDO's frame alone has
		 * nothing left for this line once that frame left */
		F->quiet_next[w] &= ~(F->mapped_slow[w] | (pinned & ~F->sourced[w]));
	}
	n = gw_fast_publish(F, F->next, until, pending, n, F->quiet_next);
	ignore_fast_frames(gl, F->next, n);
}

void gw_fast_poll(struct gw_line *gl)
{
	if (!gl->fast.by_slot)
		return;
	if (gl->fast.stale || gl->sources_gen != line_tpdo_sources_generation(gl->l)) {
		gl->sources_gen = line_tpdo_sources_generation(gl->l);
		gw_fast_refresh(gl);
	}
	gw_fast_set_carrying(&gl->fast, line_tx_idle(gl->l));
	gw_publish_done(gl);
}
