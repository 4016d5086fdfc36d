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

void line_nodes_poll(line *l)
{
	line_node_req *r = &l->node_req;

	if (atomic_load_explicit(&r->state, memory_order_acquire) != LINE_NODE_POSTED)
		return;
	r->rc = node_set(l, &r->set);
	atomic_store_explicit(&r->state, LINE_NODE_DONE, memory_order_release);
}

/* Up to 200 waits of 5 ms for the state to leave `busy`. */
static bool wait_state_not(line_node_req *r, int busy)
{
	for (int i = 0; atomic_load_explicit(&r->state, memory_order_acquire) == busy; i++) {
		if (i >= 200)
			return false;
		struct timespec ts = { .tv_nsec = 5 * 1000000L };
		nanosleep(&ts, NULL);
	}
	return true;
}

int line_request_node(line *l, const line_node_set *set)
{
	line_node_req *r = &l->node_req;

	/* one that timed out earlier may still be taken: never overwrite it */
	if (!wait_state_not(r, LINE_NODE_POSTED))
		return -EBUSY;
	r->set = *set;
	r->rc = 0;
	atomic_store_explicit(&r->state, LINE_NODE_POSTED, memory_order_release);
	line_wake(l);
	if (!wait_state_not(r, LINE_NODE_POSTED))
		return -ETIMEDOUT;
	int rc = r->rc;
	atomic_store_explicit(&r->state, LINE_NODE_FREE, memory_order_release);
	return rc;
}
