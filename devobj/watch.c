/* SPDX-License-Identifier: MIT */
/*
 * devobj/watch.c - clients watching device objects (docs/devices.md
 * "Watching values"): DEV_WATCH/UNWATCH, the line's bounded watch table,
 * MBX_EV_DEV_VALUE to each object's watchers only, at most one per watch
 * and interval (the latest value when the interval ends).
 *
 * A watch names the object, not the PDO: when the node's layout is learnt
 * again and the mirror programmed anew, the watch follows the object to
 * its new record (devobj_watch_relink); while the object is not mirrored
 * it stays and receives nothing.
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/od.h"
#include "devobj/devobj_int.h"
#include "devobj/value.h"

int devobj_watch_init(devobj_line *dl)
{
	dl->watch = calloc(dl->p.watches, sizeof *dl->watch);
	return dl->watch ? 0 : -ENOMEM;
}

void devobj_watch_fini(devobj_line *dl)
{
	free(dl->watch);
	dl->watch = NULL;
}

static devobj_rx *rx_of(devobj_line *dl, const devobj_watch *w)
{
	return w->rec >= 0 ? &dl->rx[w->rec] : NULL;
}

/* The device TPDO entry a linked watch's record carries. */
static const co_pdo_layout_entry *entry_of(const devobj_line *dl, const devobj_watch *w)
{
	const devobj_record *r = &dl->mirror.rec[CO_PDO_RX][w->rec];
	const co_pdo_layout_node *n = co_pdo_layout_node_get(line_pdo_layout(dl->l), r->node);
	return &n->pdo[CO_PDO_TX][r->dev_pos].map[w->pos];
}

static void link_watch(devobj_line *dl, int16_t k)
{
	devobj_watch *w = &dl->watch[k];
	devobj_place at;
	w->rec = -1;
	w->next = DEVOBJ_NO_WATCH;
	if (!devobj_find(dl, w->node, CO_PDO_TX, w->index, w->sub, &at) || at.rec < 0)
		return;
	w->rec = (int16_t)at.rec;
	w->pos = at.pos;
	w->next = dl->rx[at.rec].first_watch;
	dl->rx[at.rec].first_watch = k;
}

static void unlink_watch(devobj_line *dl, int16_t k)
{
	devobj_watch *w = &dl->watch[k];
	devobj_rx *rx = rx_of(dl, w);
	if (!rx)
		return;
	for (int16_t *p = &rx->first_watch; *p != DEVOBJ_NO_WATCH; p = &dl->watch[*p].next) {
		if (*p == k) {
			*p = w->next;
			break;
		}
	}
	w->rec = -1;
}

void devobj_watch_relink(devobj_line *dl)
{
	for (unsigned i = 0; i < dl->mirror.n_rec[CO_PDO_RX]; i++)
		dl->rx[i].first_watch = DEVOBJ_NO_WATCH;
	for (unsigned k = 0; k < dl->p.watches; k++)
		if (dl->watch[k].used)
			link_watch(dl, (int16_t)k);
}

/* MBX_EV_DEV_VALUE with the record's last value. */
static void send_value(devobj_line *dl, devobj_watch *w, uint64_t now_us)
{
	const devobj_rx *rx = rx_of(dl, w);
	const co_pdo_layout_entry *e = entry_of(dl, w);
	uint8_t buf[sizeof(mbx_dev_value) + MBX_DEV_VALUE_EVENT_MAX];
	mbx_dev_value v = {
		.node = w->node,
		.sub = w->sub,
		.index = w->index,
		.type = devobj_value_type(e, w->type),
		.via = MBX_DEV_VIA_PDO,
		.bits = e->bits,
		.seq = ++w->seq,
		.time_us = rx->time_us,
	};
	v.len = devobj_value_extract(rx->frame, e, v.type, buf + sizeof v);
	memcpy(buf, &v, sizeof v);
	w->sent_us = now_us;
	w->pending = false;
	/* a full client queue drops it, counted by the mailbox; the gap in
	 * seq tells the client */
	mbx_server_notify(line_mbx(dl->l), &w->reply, MBX_EV_DEV_VALUE, buf, sizeof v + v.len);
}

static bool interval_over(const devobj_watch *w, uint64_t now_us)
{
	return w->seq == 0 || now_us >= w->sent_us + (uint64_t)w->interval_ms * 1000u;
}

void devobj_watch_received(devobj_line *dl, unsigned rec, uint64_t now_us)
{
	for (int16_t k = dl->rx[rec].first_watch; k != DEVOBJ_NO_WATCH; k = dl->watch[k].next) {
		devobj_watch *w = &dl->watch[k];
		if (interval_over(w, now_us))
			send_value(dl, w, now_us);
		else
			w->pending = true;
	}
}

uint64_t devobj_watch_poll(devobj_line *dl, uint64_t now_us)
{
	uint64_t next = CO_NO_DEADLINE;
	for (unsigned k = 0; k < dl->p.watches && dl->n_watch_used; k++) {
		devobj_watch *w = &dl->watch[k];
		if (!w->used || !w->pending || w->rec < 0)
			continue;
		if (interval_over(w, now_us)) {
			send_value(dl, w, now_us);
			continue;
		}
		uint64_t due = w->sent_us + (uint64_t)w->interval_ms * 1000u;
		if (due < next)
			next = due;
	}
	return next;
}

static int16_t find_watch(const devobj_line *dl, uint32_t client, const mbx_dev_obj_req *o)
{
	for (unsigned k = 0; k < dl->p.watches; k++) {
		const devobj_watch *w = &dl->watch[k];
		if (w->used && w->reply.client == client && w->node == o->node &&
		    w->index == o->index && w->sub == o->sub)
			return (int16_t)k;
	}
	return DEVOBJ_NO_WATCH;
}

static void drop_watch(devobj_line *dl, int16_t k)
{
	unlink_watch(dl, k);
	dl->watch[k].used = false;
	dl->n_watch_used--;
}

void devobj_cmd_watch(devobj_line *dl, const mbx_request *req)
{
	mbx_dev_watch_req r;
	devobj_place at;
	memcpy(&r, req->payload, sizeof r);

	/* only what a TPDO of the device carries can be watched; the mirror
	 * must consume that PDO (pdo "auto" and it fitted) */
	if (!devobj_find(dl, r.obj.node, CO_PDO_TX, r.obj.index, r.obj.sub, &at))
		return devobj_answer(dl, &req->reply, MBX_E_NOT_FOUND, 0, NULL, 0);
	if (at.rec < 0)
		return devobj_answer(dl, &req->reply, MBX_E_STATE, 0, NULL, 0);
	if (r.obj.flags & MBX_DEV_SDO_ONLY)
		return devobj_answer(dl, &req->reply, MBX_E_PARAM, 0, NULL, 0);
	uint16_t type = devobj_value_type(at.entry, r.obj.type);
	if (!type || (r.obj.type && at.entry->type && r.obj.type != at.entry->type))
		return devobj_answer(dl, &req->reply, MBX_E_ABORT, SDO_AB_TYPE_LEN, NULL, 0);

	/* the same object again: a new interval and type, the same watch */
	int16_t k = find_watch(dl, req->reply.client, &r.obj);
	if (k != DEVOBJ_NO_WATCH) {
		drop_watch(dl, k);
	} else {
		for (unsigned i = 0; i < dl->p.watches && k == DEVOBJ_NO_WATCH; i++)
			if (!dl->watch[i].used)
				k = (int16_t)i;
	}
	if (k == DEVOBJ_NO_WATCH) {
		dl->watch_refused++;
		return devobj_answer(dl, &req->reply, MBX_E_FULL, 0, NULL, 0);
	}
	devobj_watch *w = &dl->watch[k];
	*w = (devobj_watch){
		.used = true,
		.node = r.obj.node,
		.sub = r.obj.sub,
		.index = r.obj.index,
		.type = r.obj.type,
		.interval_ms = r.min_interval_ms,
		.reply = req->reply,
		.rec = -1,
		.next = DEVOBJ_NO_WATCH,
	};
	dl->n_watch_used++;
	link_watch(dl, k);
	mbx_dev_watch_resp resp = { .type = type, .pdo = at.pdo->nr, .cob_id = at.pdo->cob };
	devobj_answer(dl, &req->reply, 0, 0, &resp, sizeof resp);
	/* a value already received comes at once: a client that starts
	 * watching needs the present state, not only the next change */
	if (dl->rx[w->rec].count)
		send_value(dl, w, line_loop_now_us(dl->l));
}

void devobj_cmd_unwatch(devobj_line *dl, const mbx_request *req)
{
	mbx_dev_obj_req o;
	memcpy(&o, req->payload, sizeof o);
	int16_t k = find_watch(dl, req->reply.client, &o);
	if (k == DEVOBJ_NO_WATCH)
		return devobj_answer(dl, &req->reply, MBX_E_NOT_FOUND, 0, NULL, 0);
	drop_watch(dl, k);
	devobj_answer(dl, &req->reply, 0, 0, NULL, 0);
}

void devobj_watch_client_gone(devobj_line *dl, uint32_t client)
{
	for (unsigned k = 0; k < dl->p.watches; k++)
		if (dl->watch[k].used && dl->watch[k].reply.client == client)
			drop_watch(dl, (int16_t)k);
}
