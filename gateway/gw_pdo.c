/* SPDX-License-Identifier: MIT */
/*
 * gateway/gw_pdo.c - PDO forwarding at run time: a B-object written on this
 * line goes into the shared image (gateway/image.h) and, as a message, to
 * every line whose TPDOs map it; an update from another line is applied to
 * this line's OD and triggers its TPDOs; after a drop, the image's latest
 * value (gateway/pdo_sync.h).
 */
#include <string.h>

#include "core/od.h"
#include "core/pdo.h"
#include "gateway/gw_line.h"

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
		if (gw_send_to(gl, j, &m)) {
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

/* An update from another line, in the order its source wrote them. */
void gw_pdo_received(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	pdo_apply(gl, m->slot, m->bits, false, now_us);
	gw_pdo_sync_received(&gl->lost, gl->g->img, m->slot, m->bits);
}

/* gw_pdo_sync_apply_fn: a resync, which must not trigger a TPDO for a
 * value this line already holds. */
bool gw_pdo_resync_apply(void *ctx, int slot, uint64_t bits)
{
	struct gw_line *gl = ctx;

	return pdo_apply(gl, slot, bits, true, line_loop_now_us(gl->l));
}
