/* SPDX-License-Identifier: MIT */
/*
 * The core instance: receive dispatch, service plumbing, deadlines.
 *
 * Dispatch follows the kernel's can_rcv_lists idea: a direct table indexed
 * by the 11-bit identifier (2048 x 2 bytes per node) gives the first
 * receiver in O(1); receivers sharing an id form a short chain. 29-bit ids
 * are rare in CANopen (bit 29 of a COB-ID), so a small sorted table with a
 * binary search is enough for them.
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/co.h"
#include "core/co_internal.h"
#include "core/commfault.h"
#include "core/emcy.h"
#include "core/errctrl.h"
#include "core/guarding.h"
#include "core/heartbeat.h"
#include "core/lss.h"
#include "core/nmt.h"
#include "core/pdo.h"
#include "core/sdo_client.h"
#include "core/sdo_server.h"
#include "core/store.h"
#include "core/sync.h"
#include "core/time.h"

/* Services in init/tick order. To add one: one line here (see co.h). */
static const co_service *const co_services[] = {
	&co_svc_lss, /* first: its reset_comm makes the LSS pending node-ID
	              * active (node->node_id) before the others read it */
	&co_svc_sdo_server, &co_svc_sdo_client,
	&co_svc_store,      &co_svc_nmt,     /* before the error control services: boot-up first */
	&co_svc_emcy,       &co_svc_errctrl, /* before heartbeat and guarding, which report to it */
	&co_svc_commfault,                   /* after EMCY, which it raises */
	&co_svc_hb,         &co_svc_guard,
	&co_svc_sync, /* before PDO: a produced SYNC drives the PDOs */
	&co_svc_time,       &co_svc_pdo,
};

#define N_SERVICES (sizeof(co_services) / sizeof(co_services[0]))

struct co_rx {
	co_rx_fn fn;
	void *arg;
	uint64_t hits;
	uint32_t id;
	uint16_t next; /* next receiver + 1 in the chain or free list */
	uint8_t flags; /* CO_FRAME_EXT */
	uint8_t in_use : 1;
	uint8_t attached : 1;
};

struct co_rx_ext {
	uint32_t id;
	uint16_t head; /* receiver + 1 */
};

/* ---- receive dispatch ---------------------------------------------------- */

static bool id_ok(uint32_t id, uint8_t flags)
{
	return (flags & CO_FRAME_EXT) ? !(id & ~CO_FRAME_EFF_MASK) : !(id & ~CO_FRAME_SFF_MASK);
}

static size_t ext_find(const co_node *node, uint32_t id, bool *found)
{
	size_t lo = 0, hi = node->rx_ext_count;

	while (lo < hi) {
		size_t mid = lo + (hi - lo) / 2;
		if (node->rx_ext[mid].id < id)
			lo = mid + 1;
		else
			hi = mid;
	}
	*found = lo < node->rx_ext_count && node->rx_ext[lo].id == id;
	return lo;
}

/* Slot holding the chain head for (id, flags); NULL if none and !create. */
static uint16_t *chain_head(co_node *node, uint32_t id, uint8_t flags, bool create)
{
	bool found;
	size_t pos;

	if (!(flags & CO_FRAME_EXT))
		return &node->rx_sff[id];
	pos = ext_find(node, id, &found);
	if (found)
		return &node->rx_ext[pos].head;
	if (!create || node->rx_ext_count >= node->cfg.rx_ext_max)
		return NULL;
	memmove(&node->rx_ext[pos + 1], &node->rx_ext[pos],
		(node->rx_ext_count - pos) * sizeof(*node->rx_ext));
	node->rx_ext[pos].id = id;
	node->rx_ext[pos].head = 0;
	node->rx_ext_count++;
	return &node->rx_ext[pos].head;
}

static void ext_drop_if_empty(co_node *node, uint32_t id)
{
	bool found;
	size_t pos = ext_find(node, id, &found);

	if (found && node->rx_ext[pos].head == 0) {
		memmove(&node->rx_ext[pos], &node->rx_ext[pos + 1],
			(node->rx_ext_count - pos - 1) * sizeof(*node->rx_ext));
		node->rx_ext_count--;
	}
}

static int rx_attach(co_node *node, int h, uint32_t id, uint8_t flags)
{
	struct co_rx *r = &node->rx[h];
	uint16_t *slot = chain_head(node, id, flags, true);

	if (!slot)
		return -ENOSPC;
	r->id = id;
	r->flags = flags & CO_FRAME_EXT;
	r->next = 0;
	while (*slot) /* append: receivers run in registration order */
		slot = &node->rx[*slot - 1].next;
	*slot = (uint16_t)(h + 1);
	r->attached = 1;
	return 0;
}

static void rx_detach(co_node *node, int h)
{
	struct co_rx *r = &node->rx[h];
	uint16_t *slot;

	if (!r->attached)
		return;
	slot = chain_head(node, r->id, r->flags, false);
	while (slot && *slot) {
		if (*slot == h + 1) {
			*slot = r->next;
			break;
		}
		slot = &node->rx[*slot - 1].next;
	}
	r->attached = 0;
	r->next = 0;
	if (r->flags & CO_FRAME_EXT)
		ext_drop_if_empty(node, r->id);
}

static bool handle_ok(const co_node *node, int h)
{
	return h >= 0 && h < node->cfg.rx_max && node->rx[h].in_use;
}

int co_rx_register(co_node *node, uint32_t id, uint8_t flags, co_rx_fn fn, void *arg)
{
	int h, rc;

	if (!fn || !id_ok(id, flags))
		return -EINVAL;
	if (!node->rx_free)
		return -ENOSPC;
	h = node->rx_free - 1;
	node->rx_free = node->rx[h].next;
	memset(&node->rx[h], 0, sizeof(node->rx[h]));
	node->rx[h].fn = fn;
	node->rx[h].arg = arg;
	node->rx[h].in_use = 1;
	rc = rx_attach(node, h, id, flags);
	if (rc) {
		node->rx[h].in_use = 0;
		node->rx[h].next = node->rx_free;
		node->rx_free = (uint16_t)(h + 1);
		return rc;
	}
	return h;
}

int co_rx_move(co_node *node, int h, uint32_t id, uint8_t flags)
{
	if (!handle_ok(node, h) || !id_ok(id, flags))
		return -EINVAL;
	if (node->rx[h].attached && node->rx[h].id == id &&
	    node->rx[h].flags == (flags & CO_FRAME_EXT))
		return 0;
	rx_detach(node, h);
	return rx_attach(node, h, id, flags);
}

int co_rx_disable(co_node *node, int h)
{
	if (!handle_ok(node, h))
		return -EINVAL;
	rx_detach(node, h);
	return 0;
}

int co_rx_unregister(co_node *node, int h)
{
	if (!handle_ok(node, h))
		return -EINVAL;
	rx_detach(node, h);
	node->rx[h].in_use = 0;
	node->rx[h].next = node->rx_free;
	node->rx_free = (uint16_t)(h + 1);
	return 0;
}

uint64_t co_rx_hits(const co_node *node, int h)
{
	return handle_ok(node, h) ? node->rx[h].hits : 0;
}

int co_node_recv(co_node *node, const co_frame *f, uint64_t now_us)
{
	uint16_t *slot;
	uint16_t cur;

	node->stats.rx_frames++;
	if (!co_frame_is_valid(f)) {
		node->stats.rx_invalid++;
		return -EINVAL;
	}
	node->now_us = now_us;
	slot = chain_head(node, f->id, f->flags, false);
	cur = slot ? *slot : 0;
	if (!cur) {
		node->stats.rx_unhandled++;
		if (node->cfg.report_unhandled) {
			co_event ev = { .kind = CO_EV_RX_UNHANDLED };
			ev.u.frame = *f;
			co_node_emit(node, &ev);
		}
		return 0;
	}
	while (cur) {
		struct co_rx *r = &node->rx[cur - 1];
		uint16_t next = r->next;
		r->hits++;
		r->fn(node, r->arg, f, now_us);
		/* The handler may have (un)registered receivers: only follow
		 * the chain while the next one still listens to this frame. */
		if (next) {
			const struct co_rx *n = &node->rx[next - 1];
			if (!n->in_use || !n->attached || n->id != f->id ||
			    n->flags != (f->flags & CO_FRAME_EXT))
				break;
		}
		cur = next;
	}
	return 0;
}

/* ---- output, events, deadlines ------------------------------------------ */

int co_node_send(co_node *node, const co_frame *f)
{
	int rc = node->cfg.send(node->cfg.send_ctx, f);

	if (rc < 0) {
		node->stats.tx_failed++;
		co_event ev = { .kind = CO_EV_TX_FAILED };
		ev.u.frame = *f;
		co_node_emit(node, &ev);
		return rc;
	}
	node->stats.tx_frames++;
	return 0;
}

void co_node_emit(co_node *node, co_event *ev)
{
	if (!node->cfg.event)
		return;
	ev->now_us = node->now_us;
	node->cfg.event(node->cfg.event_ctx, ev);
}

void co_node_deadline_lower(co_node *node, uint64_t t)
{
	if (t < node->deadline_us)
		node->deadline_us = t;
}

uint64_t co_node_tick(co_node *node, uint64_t now_us)
{
	uint64_t next = CO_NO_DEADLINE;

	node->now_us = now_us;
	/* Reset first: a service arming a timer inside another's tick (via
	 * co_node_deadline_lower) must not be lost. */
	node->deadline_us = CO_NO_DEADLINE;
	for (size_t i = 0; i < N_SERVICES; i++) {
		if (!co_services[i]->tick)
			continue;
		uint64_t t = co_services[i]->tick(node, now_us);
		if (t < next)
			next = t;
	}
	co_node_deadline_lower(node, next);
	return node->deadline_us;
}

uint64_t co_node_next_deadline_us(const co_node *node)
{
	return node->deadline_us;
}

co_od *co_node_od(const co_node *node)
{
	return node->od;
}

uint8_t co_node_id(const co_node *node)
{
	return node->node_id;
}

const co_node_stats *co_node_get_stats(const co_node *node)
{
	return &node->stats;
}

void co_node_reset_comm(co_node *node, uint64_t now_us)
{
	node->now_us = now_us;
	co_od_reset_range(node->od, 0x1000, 0x1FFF);
	for (size_t i = 0; i < N_SERVICES; i++)
		if (co_services[i]->reset_comm)
			co_services[i]->reset_comm(node, now_us);
}

void co_node_reset_app(co_node *node, uint64_t now_us)
{
	co_od_reset_range(node->od, 0x0000, 0xFFFF);
	co_node_reset_comm(node, now_us);
}

void co_node_nmt_changed(co_node *node, uint8_t new_state, uint64_t now_us)
{
	node->now_us = now_us;
	for (size_t i = 0; i < N_SERVICES; i++)
		if (co_services[i]->nmt_changed)
			co_services[i]->nmt_changed(node, new_state, now_us);
}

/* ---- lifetime ---------------------------------------------------------- */

static void cfg_defaults(co_node_config *c)
{
	if (!c->rx_max)
		c->rx_max = 512;
	if (!c->rx_ext_max)
		c->rx_ext_max = 32;
	if (!c->sdo_server_count)
		c->sdo_server_count = 1;
	if (!c->sdo_server_timeout_ms)
		c->sdo_server_timeout_ms = 1000;
	if (!c->sdo_server_blksize || c->sdo_server_blksize > 127)
		c->sdo_server_blksize = 127;
	if (!c->sdo_stage_size)
		c->sdo_stage_size = 1024;
	if (c->sdo_stage_size < 8)
		c->sdo_stage_size = 8;
	if (!c->sdo_client_queue_len)
		c->sdo_client_queue_len = 8;
	if (!c->sdo_client_pool_len) {
		unsigned n = (unsigned)c->sdo_client_queue_len * c->sdo_client_count;
		c->sdo_client_pool_len = (uint16_t)(n == 0 ? 1 : n > 1024 ? 1024 : n);
	}
	if (!c->sdo_client_timeout_ms)
		c->sdo_client_timeout_ms = 1000;
	if (!c->sdo_client_block_threshold)
		c->sdo_client_block_threshold = 128;
	if (!c->sdo_client_blksize || c->sdo_client_blksize > 127)
		c->sdo_client_blksize = 127;
}

int co_node_create(co_node **out, const co_node_config *cfg)
{
	co_node *node;
	int rc;

	if (!out || !cfg || !cfg->od || !cfg->send)
		return -EINVAL;
	if (!((cfg->node_id >= 1 && cfg->node_id <= 127) || cfg->node_id == 255))
		return -EINVAL;
	if (cfg->sdo_server_count > SDO_MAX_CHANNELS || cfg->sdo_client_count > SDO_MAX_CHANNELS)
		return -EINVAL;
	node = calloc(1, sizeof(*node));
	if (!node)
		return -ENOMEM;
	node->cfg = *cfg;
	cfg_defaults(&node->cfg);
	node->od = cfg->od;
	node->node_id = cfg->node_id;
	node->deadline_us = CO_NO_DEADLINE;
	node->rx = calloc(node->cfg.rx_max, sizeof(*node->rx));
	node->rx_ext = calloc(node->cfg.rx_ext_max, sizeof(*node->rx_ext));
	if (!node->rx || !node->rx_ext) {
		rc = -ENOMEM;
		goto fail;
	}
	for (uint16_t i = 0; i < node->cfg.rx_max; i++)
		node->rx[i].next = (uint16_t)(i + 2 <= node->cfg.rx_max ? i + 2 : 0);
	node->rx_free = 1;
	for (size_t i = 0; i < N_SERVICES; i++) {
		if (co_services[i]->init && (rc = co_services[i]->init(node)) != 0)
			goto fail;
	}
	*out = node;
	return 0;
fail:
	co_node_destroy(node);
	return rc;
}

void co_node_destroy(co_node *node)
{
	if (!node)
		return;
	for (size_t i = N_SERVICES; i-- > 0;)
		if (co_services[i]->fini)
			co_services[i]->fini(node);
	free(node->rx_ext);
	free(node->rx);
	free(node);
}
