/* SPDX-License-Identifier: MIT */
/*
 * lines/line_nodes.c - nodes added, changed and removed at run time
 * (docs/config.md "Nodes at run time"): a reload's change handed from the
 * main thread to the line thread, applied there by the extension that
 * keeps the network list (the manager), and the news of an applied change
 * to the other extensions (the device object layer).
 */
#include <errno.h>
#include <time.h>

#include "lines/line_internal.h"

void line_node_changed(line *l, const line_node_news *info)
{
	for (unsigned i = 0; i < l->ext_attached; i++) {
		const line_ext *x = &l->p.ext[i];
		if (x->ops && x->ops->node_changed)
			x->ops->node_changed(x->ctx, l, info);
	}
}

static int node_set(line *l, const line_node_set *set)
{
	for (unsigned i = 0; i < l->ext_attached; i++) {
		const line_ext *x = &l->p.ext[i];
		if (x->ops && x->ops->node_set)
			return x->ops->node_set(x->ctx, l, set);
	}
	return -EOPNOTSUPP;
}

/* 1016h: the sub-index consuming `node`, else (want_free) a free one. */
static co_od_entry *consumer_entry(co_od *od, uint8_t node, bool want_free)
{
	co_od_entry *free_entry = NULL;
	uint8_t subs = 0;

	(void)co_od_get_u8(od, 0x1016, 0, &subs);
	for (unsigned sub = 1; sub <= subs; sub++) {
		co_od_entry *e = co_od_find(od, 0x1016, (uint8_t)sub);
		uint32_t v = 0;
		(void)co_od_get_u32(od, 0x1016, (uint8_t)sub, &v);
		if (((v >> 16) & 0xFFu) == node && (v & 0xFFFFu))
			return e;
		if (!free_entry && !(v & 0xFFFFu))
			free_entry = e;
	}
	return want_free ? free_entry : NULL;
}

/* Through the OD's hooks, as an SDO write: the heartbeat consumer loads
 * the entry again (core/heartbeat.h). */
int line_consumer_set(line *l, uint8_t node, uint16_t time_ms)
{
	co_od *od = co_node_od(l->node);
	co_od_entry *e = consumer_entry(od, node, false);
	uint32_t v = (uint32_t)node << 16 | time_ms, ab = 0;
	uint8_t zero[4] = { 0 }, b[4] = { (uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), 0 };
	co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL };

	if (e && (ab = co_od_write(e, zero, sizeof zero, &a)))
		return -EIO;
	if (!time_ms)
		return 0;
	if (!(e = consumer_entry(od, node, true)))
		return -ENOSPC;
	return co_od_write(e, b, sizeof b, &a) ? -EIO : 0;
}

void line_nodes_poll(line *l)
{
	line_node_req *r = &l->node_req;

	if (atomic_load_explicit(&r->state, memory_order_acquire) != LINE_NODE_POSTED)
		return;
	r->rc = r->consumer_only ? line_consumer_set(l, r->set.req.node, r->set.req.heartbeat_ms)
				 : node_set(l, &r->set);
	atomic_store_explicit(&r->state, LINE_NODE_DONE, memory_order_release);
}

static int post(line *l, const line_node_set *set, bool consumer_only)
{
	line_node_req *r = &l->node_req;

	/* one that timed out earlier may still be taken: never overwrite it */
	if (!line_wait_state_leaves(&r->state, LINE_NODE_POSTED))
		return -EBUSY;
	r->set = *set;
	r->consumer_only = consumer_only;
	r->rc = 0;
	atomic_store_explicit(&r->state, LINE_NODE_POSTED, memory_order_release);
	line_wake(l);
	if (!line_wait_state_leaves(&r->state, LINE_NODE_POSTED))
		return -ETIMEDOUT;
	int rc = r->rc;
	atomic_store_explicit(&r->state, LINE_NODE_FREE, memory_order_release);
	return rc;
}

int line_request_node(line *l, const line_node_set *set)
{
	return post(l, set, false);
}

int line_request_consumer(line *l, uint8_t node, uint16_t time_ms)
{
	line_node_set set = { .req = { .node = node, .heartbeat_ms = time_ms } };
	return post(l, &set, true);
}
