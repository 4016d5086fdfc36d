/* SPDX-License-Identifier: MIT */
/*
 * TIME producer/consumer (CiA 301 §7.2.6) and TIME_OF_DAY coding.
 *
 * The service is small on purpose: one receiver on the 1012h CAN-ID while
 * bit 31 is set, one frame out per co_time_send(). Reconfiguration goes
 * through the 1012h hooks so an SDO write takes effect at once.
 */
#include <errno.h>
#include <stdlib.h>

#include "core/co_internal.h"
#include "core/nmt.h"
#include "core/sdo.h"
#include "core/time.h"

#define TIME_IDX 0x1012u

struct co_time {
	co_node *node;
	co_od_entry *e_cob; /* NULL: no 1012h */
	uint32_t cob;       /* value in force */
	int rx_h;           /* receiver, detached unless consuming */
	bool have_last;
	co_time_of_day last;
	co_time_stats stats;
};

/* ---- TIME_OF_DAY --------------------------------------------------------- */

int co_time_encode(const co_time_of_day *t, uint8_t out[CO_TIME_FRAME_LEN])
{
	if (!t || !out || t->ms >= CO_TIME_MS_PER_DAY)
		return -EINVAL;
	co_put_le32(out, t->ms & CO_TIME_MS_MASK); /* reserved bits 28..31 = 0 */
	co_put_le16(out + 4, t->days);
	return 0;
}

int co_time_decode(const uint8_t *in, uint32_t len, co_time_of_day *t)
{
	uint32_t ms;

	if (!in || !t || len < CO_TIME_FRAME_LEN)
		return -EINVAL;
	ms = co_get_le32(in) & CO_TIME_MS_MASK;
	if (ms >= CO_TIME_MS_PER_DAY)
		return -EINVAL;
	t->ms = ms;
	t->days = co_get_le16(in + 4);
	return 0;
}

int co_time_from_unix_ms(int64_t unix_ms, co_time_of_day *t)
{
	int64_t since;

	if (!t)
		return -EINVAL;
	since = unix_ms - CO_TIME_EPOCH_UNIX_S * 1000;
	if (since < 0 || since / CO_TIME_MS_PER_DAY > UINT16_MAX)
		return -ERANGE;
	t->days = (uint16_t)(since / CO_TIME_MS_PER_DAY);
	t->ms = (uint32_t)(since % CO_TIME_MS_PER_DAY);
	return 0;
}

int64_t co_time_to_unix_ms(const co_time_of_day *t)
{
	return CO_TIME_EPOCH_UNIX_S * 1000 + (int64_t)t->days * CO_TIME_MS_PER_DAY + t->ms;
}

/* ---- service ------------------------------------------------------------- */

static bool time_state_ok(const co_node *node)
{
	uint8_t s = co_nmt_get_state(node);

	return s == CO_NMT_OPERATIONAL || s == CO_NMT_PRE_OPERATIONAL;
}

static void time_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	struct co_time *T = arg;
	co_time_of_day t;
	co_event ev = { .kind = CO_EV_TIME };

	(void)now_us;
	if (f->flags & CO_FRAME_RTR)
		return;
	if (!time_state_ok(node)) {
		T->stats.rx_ignored++;
		return;
	}
	if (co_time_decode(f->data, f->len, &t) != 0) {
		T->stats.rx_invalid++;
		return;
	}
	T->stats.rx++;
	T->last = t;
	T->have_last = true;
	ev.u.time.ms = t.ms;
	ev.u.time.days = t.days;
	co_node_emit(node, &ev);
}

static void time_apply(struct co_time *T)
{
	uint32_t id;
	uint8_t flags;

	T->cob = T->e_cob ? (uint32_t)co_od_entry_raw(T->e_cob) : 0;
	co_cob_split(T->cob, &id, &flags);
	if (T->rx_h >= 0 && (T->cob & CO_TIME_CONSUMER))
		co_rx_move(T->node, T->rx_h, id, flags);
	else if (T->rx_h >= 0)
		co_rx_disable(T->node, T->rx_h);
}

/* 1012h: the CAN-ID may change only while neither produced nor consumed. */
static uint32_t time_check_write(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct co_time *T = ctx;
	uint32_t v, keep = CO_TIME_EXT | CO_FRAME_EFF_MASK;

	(void)e;
	if (!a->data || a->size != 4)
		return SDO_AB_TYPE_LEN;
	v = co_get_le32(a->data);
	if (!(v & CO_TIME_EXT) && (v & CO_FRAME_EFF_MASK & ~CO_FRAME_SFF_MASK))
		return SDO_AB_VALUE;
	if ((T->cob & (CO_TIME_CONSUMER | CO_TIME_PRODUCER)) &&
	    (v & (CO_TIME_CONSUMER | CO_TIME_PRODUCER)) && (v & keep) != (T->cob & keep))
		return SDO_AB_VALUE;
	return 0;
}

static void time_after_write(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)e;
	(void)a;
	time_apply(ctx);
}

static const co_od_hooks time_hooks = {
	.check_write = time_check_write,
	.after_write = time_after_write,
};

static int time_init(co_node *node)
{
	struct co_time *T = calloc(1, sizeof(*T));
	int h;

	if (!T)
		return -ENOMEM;
	T->node = node;
	T->rx_h = -1;
	node->time = T;
	T->e_cob = co_od_find(node->od, TIME_IDX, 0);
	if (!T->e_cob)
		return 0;
	co_od_entry_set_hooks(T->e_cob, &time_hooks, T);
	h = co_rx_register(node, CO_TIME_COB_DEFAULT, 0, time_rx, T);
	if (h < 0)
		return h;
	T->rx_h = h;
	time_apply(T);
	return 0;
}

static void time_fini(co_node *node)
{
	struct co_time *T = node->time;

	if (!T)
		return;
	if (T->e_cob)
		co_od_entry_set_hooks(T->e_cob, NULL, NULL);
	if (T->rx_h >= 0)
		co_rx_unregister(node, T->rx_h);
	free(T);
	node->time = NULL;
}

static void time_reset_comm(co_node *node, uint64_t now_us)
{
	(void)now_us;
	if (node->time)
		time_apply(node->time);
}

const co_service co_svc_time = {
	.name = "time",
	.init = time_init,
	.fini = time_fini,
	.reset_comm = time_reset_comm,
};

int co_time_send(co_node *node, const co_time_of_day *t, uint64_t now_us)
{
	struct co_time *T = node->time;
	co_frame f;
	uint32_t id;
	uint8_t flags;
	int rc;

	if (!T)
		return -ENODEV;
	if (!(T->cob & CO_TIME_PRODUCER))
		return -EPERM;
	if (!time_state_ok(node))
		return -EAGAIN;
	co_cob_split(T->cob, &id, &flags);
	co_frame_init(&f, id, CO_TIME_FRAME_LEN);
	f.flags = flags;
	if (co_time_encode(t, f.data) != 0)
		return -EINVAL;
	rc = co_node_send(node, &f);
	if (rc == 0) {
		co_event ev = { .kind = CO_EV_TIME };
		T->stats.tx++;
		node->now_us = now_us; /* the event's time stamp */
		ev.u.time.ms = t->ms;
		ev.u.time.days = t->days;
		ev.u.time.produced = 1;
		co_node_emit(node, &ev);
	}
	return rc;
}

int co_time_last(const co_node *node, co_time_of_day *t)
{
	const struct co_time *T = node->time;

	if (!T || !T->have_last)
		return -ENODATA;
	*t = T->last;
	return 0;
}

const co_time_stats *co_time_get_stats(const co_node *node)
{
	static const co_time_stats none;

	return node->time ? &node->time->stats : &none;
}

int co_od_add_comm_defaults_time(co_od *od, uint32_t cob_id)
{
	int rc;

	if (co_od_find(od, TIME_IDX, 0))
		return 0;
	rc = co_od_add_num(od, TIME_IDX, 0, CO_T_UNSIGNED32, CO_ACC_RW,
			   cob_id ? cob_id : CO_TIME_COB_DEFAULT, NULL);
	return rc;
}
