/* SPDX-License-Identifier: MIT */
/*
 * SYNC producer/consumer (CiA 301 §7.2.5, objects 1005h, 1006h, 1007h,
 * 1019h). See core/sync.h for the contract.
 *
 * The producer is one absolute deadline (next_us); the consumer is one
 * receiver. Both feed sync_occurred(), which is the single place that
 * tells the observers (the PDO service registers one), so a produced and
 * a consumed SYNC behave alike. SYNC does not know PDO: the observer is an
 * operation handed in, which keeps the call graph of core/ free of cycles.
 */
#include <errno.h>
#include <stdlib.h>

#include "core/co_internal.h"
#include "core/emcy.h"
#include "core/nmt.h"
#include "core/sdo.h"
#include "core/sync.h"

#define SYNC_COB_IDX 0x1005u
#define SYNC_PERIOD_IDX 0x1006u
#define SYNC_WINDOW_IDX 0x1007u
#define SYNC_OVERFLOW_IDX 0x1019u

struct co_sync {
	co_node *node;
	co_od_entry *e_cob, *e_period, *e_window, *e_overflow;
	uint32_t cob;
	uint32_t period_us;
	uint32_t window_us;
	uint8_t overflow;
	uint8_t counter;   /* last counter sent or received */
	bool active_state; /* NMT state allows SYNC (PRE-OP / OPERATIONAL) */
	bool len_err;      /* EMCY 8240h raised and not yet cleared */
	int rx_h;
	uint64_t next_us; /* producer deadline, CO_NO_DEADLINE when idle */
	uint64_t last_us; /* last SYNC, CO_NO_DEADLINE when none */
	co_sync_stats stats;
	struct {
		co_sync_ind_fn fn;
		void *ctx;
	} obs[CO_SYNC_OBSERVERS_MAX];
	uint8_t n_obs;
};

static bool state_allows_sync(uint8_t s)
{
	return s == CO_NMT_OPERATIONAL || s == CO_NMT_PRE_OPERATIONAL;
}

static bool producing(const struct co_sync *S)
{
	return (S->cob & CO_SYNC_PRODUCER) && S->period_us > 0;
}

/* Everything that happens at a SYNC, produced or consumed. */
static void sync_occurred(struct co_sync *S, uint8_t counter, bool produced, uint64_t now_us)
{
	co_event ev = { .kind = CO_EV_SYNC };

	S->counter = counter;
	S->last_us = now_us;
	ev.u.sync.counter = counter;
	ev.u.sync.produced = produced;
	co_node_emit(S->node, &ev);
	for (unsigned i = 0; i < S->n_obs; i++)
		S->obs[i].fn(S->node, S->obs[i].ctx, counter, now_us);
}

/* Restart the producer one period from now (CiA 301: the counter starts
 * again at 1 whenever the producer starts). */
static void producer_restart(struct co_sync *S, uint64_t now_us)
{
	if (producing(S) && S->active_state) {
		S->counter = 0;
		S->next_us = now_us + S->period_us;
		co_node_deadline_lower(S->node, S->next_us);
	} else {
		S->next_us = CO_NO_DEADLINE;
	}
}

static void producer_send(struct co_sync *S, uint64_t now_us)
{
	co_frame f;
	uint32_t id;
	uint8_t flags;

	co_cob_split(S->cob, &id, &flags);
	co_frame_init(&f, id, 0);
	f.flags = flags;
	if (S->overflow) {
		/* counter runs 1..overflow, then starts again at 1 */
		uint8_t c = S->counter >= S->overflow ? 1 : S->counter + 1;
		f.len = 1;
		f.data[0] = c;
		S->counter = c;
	}
	if (co_node_send(S->node, &f) == 0)
		S->stats.tx++;
	sync_occurred(S, f.len ? f.data[0] : 0, true, now_us);
}

static void sync_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	struct co_sync *S = arg;
	uint8_t counter = 0;

	if (f->flags & CO_FRAME_RTR)
		return;
	if (producing(S) || !S->active_state) {
		S->stats.rx_ignored++;
		return;
	}
	if (S->overflow) {
		if (f->len != 1) {
			S->stats.rx_invalid++;
			if (!S->len_err) {
				S->len_err = true;
				co_emcy_send(node, CO_EMCY_SYNC_LENGTH, CO_EMCY_REG_COMM, NULL,
					     now_us);
			}
			return;
		}
		counter = f->data[0];
	}
	if (S->len_err) {
		S->len_err = false;
		co_emcy_clear(node, CO_EMCY_SYNC_LENGTH, now_us);
	}
	S->stats.rx++;
	sync_occurred(S, counter, false, now_us);
}

static uint32_t entry_u32(const co_od_entry *e, uint32_t def)
{
	return e ? (uint32_t)co_od_entry_raw(e) : def;
}

/* Re-read the objects and apply them (init, reset comm, after a write). */
static void sync_apply(struct co_sync *S, uint64_t now_us)
{
	uint32_t id, old_cob = S->cob, old_period = S->period_us;
	uint8_t flags;

	S->cob = entry_u32(S->e_cob, CO_SYNC_COB_DEFAULT);
	S->period_us = entry_u32(S->e_period, 0);
	S->window_us = entry_u32(S->e_window, 0);
	S->overflow = (uint8_t)entry_u32(S->e_overflow, 0);
	co_cob_split(S->cob, &id, &flags);
	if (S->rx_h >= 0)
		co_rx_move(S->node, S->rx_h, id, flags);
	if (old_cob != S->cob || old_period != S->period_us || S->next_us == CO_NO_DEADLINE)
		producer_restart(S, now_us);
}

/* ---- OD hooks ------------------------------------------------------------ */

static uint32_t sync_check_write(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct co_sync *S = ctx;
	uint32_t v;

	if (!a->data)
		return SDO_AB_TYPE_LEN;
	switch (e->index) {
	case SYNC_COB_IDX:
		v = co_get_le32(a->data);
		if (!(v & CO_SYNC_EXT) && (v & CO_FRAME_EFF_MASK & ~CO_FRAME_SFF_MASK))
			return SDO_AB_VALUE;
		/* CiA 301 §7.5.2.5: no new CAN-ID while producing */
		if ((S->cob & CO_SYNC_PRODUCER) && (v & CO_SYNC_PRODUCER) &&
		    (v & (CO_SYNC_EXT | CO_FRAME_EFF_MASK)) !=
			    (S->cob & (CO_SYNC_EXT | CO_FRAME_EFF_MASK)))
			return SDO_AB_VALUE;
		return 0;
	case SYNC_OVERFLOW_IDX:
		if (a->data[0] == 1 || a->data[0] > CO_SYNC_COUNTER_MAX)
			return SDO_AB_VALUE;
		if (S->period_us != 0)
			return SDO_AB_DEV_STATE;
		return 0;
	default:
		return 0;
	}
}

static void sync_after_write(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct co_sync *S = ctx;

	(void)e;
	(void)a;
	sync_apply(S, S->node->now_us);
}

static const co_od_hooks sync_hooks = {
	.check_write = sync_check_write,
	.after_write = sync_after_write,
};

/* ---- service ops --------------------------------------------------------- */

static int sync_init(co_node *node)
{
	struct co_sync *S = calloc(1, sizeof(*S));
	int h;

	if (!S)
		return -ENOMEM;
	node->sync = S;
	S->node = node;
	S->rx_h = -1;
	S->next_us = CO_NO_DEADLINE;
	S->last_us = CO_NO_DEADLINE;
	S->e_cob = co_od_find(node->od, SYNC_COB_IDX, 0);
	S->e_period = co_od_find(node->od, SYNC_PERIOD_IDX, 0);
	S->e_window = co_od_find(node->od, SYNC_WINDOW_IDX, 0);
	S->e_overflow = co_od_find(node->od, SYNC_OVERFLOW_IDX, 0);
	if (S->e_cob)
		co_od_entry_set_hooks(S->e_cob, &sync_hooks, S);
	if (S->e_period)
		co_od_entry_set_hooks(S->e_period, &sync_hooks, S);
	if (S->e_window)
		co_od_entry_set_hooks(S->e_window, &sync_hooks, S);
	if (S->e_overflow)
		co_od_entry_set_hooks(S->e_overflow, &sync_hooks, S);
	h = co_rx_register(node, CO_SYNC_COB_DEFAULT, 0, sync_rx, S);
	if (h < 0)
		return h;
	S->rx_h = h;
	S->active_state = state_allows_sync(co_nmt_get_state(node));
	sync_apply(S, node->now_us);
	return 0;
}

static void sync_fini(co_node *node)
{
	struct co_sync *S = node->sync;

	if (!S)
		return;
	if (S->e_cob)
		co_od_entry_set_hooks(S->e_cob, NULL, NULL);
	if (S->e_period)
		co_od_entry_set_hooks(S->e_period, NULL, NULL);
	if (S->e_window)
		co_od_entry_set_hooks(S->e_window, NULL, NULL);
	if (S->e_overflow)
		co_od_entry_set_hooks(S->e_overflow, NULL, NULL);
	if (S->rx_h >= 0)
		co_rx_unregister(node, S->rx_h);
	free(S);
	node->sync = NULL;
}

static uint64_t sync_tick(co_node *node, uint64_t now_us)
{
	struct co_sync *S = node->sync;

	if (!S || S->next_us == CO_NO_DEADLINE)
		return CO_NO_DEADLINE;
	if (now_us < S->next_us)
		return S->next_us;
	S->next_us += S->period_us;
	if (S->next_us <= now_us) {
		/* Late by more than one period: skip, do not burst. */
		S->stats.skipped += (now_us - S->next_us) / S->period_us + 1;
		S->next_us = now_us + S->period_us;
	}
	producer_send(S, now_us);
	/* The callbacks may have reconfigured or stopped the producer. */
	return S->next_us;
}

static void sync_reset_comm(co_node *node, uint64_t now_us)
{
	struct co_sync *S = node->sync;

	if (!S)
		return;
	S->last_us = CO_NO_DEADLINE;
	S->len_err = false;
	S->next_us = CO_NO_DEADLINE;
	sync_apply(S, now_us);
}

static void sync_nmt_changed(co_node *node, uint8_t state, uint64_t now_us)
{
	struct co_sync *S = node->sync;
	bool allow = state_allows_sync(state);

	if (!S || allow == S->active_state)
		return;
	S->active_state = allow;
	producer_restart(S, now_us);
}

const co_service co_svc_sync = {
	.name = "sync",
	.init = sync_init,
	.fini = sync_fini,
	.tick = sync_tick,
	.reset_comm = sync_reset_comm,
	.nmt_changed = sync_nmt_changed,
};

/* ---- queries ------------------------------------------------------------- */

uint8_t co_sync_counter(const co_node *node)
{
	return node->sync ? node->sync->counter : 0;
}

uint8_t co_sync_overflow(const co_node *node)
{
	return node->sync ? node->sync->overflow : 0;
}

bool co_sync_is_producer(const co_node *node)
{
	return node->sync && producing(node->sync) && node->sync->active_state;
}

uint64_t co_sync_last_us(const co_node *node)
{
	return node->sync ? node->sync->last_us : CO_NO_DEADLINE;
}

int co_sync_observer_add(co_node *node, co_sync_ind_fn fn, void *ctx)
{
	struct co_sync *S = node->sync;

	if (!fn)
		return -EINVAL;
	if (!S)
		return -ENODEV;
	if (S->n_obs >= CO_SYNC_OBSERVERS_MAX)
		return -ENOSPC;
	S->obs[S->n_obs].fn = fn;
	S->obs[S->n_obs].ctx = ctx;
	S->n_obs++;
	return 0;
}

bool co_sync_in_window(const co_node *node, uint64_t now_us)
{
	const struct co_sync *S = node->sync;

	if (!S || S->window_us == 0)
		return true;
	if (S->last_us == CO_NO_DEADLINE)
		return false;
	return now_us <= S->last_us + S->window_us;
}

const co_sync_stats *co_sync_get_stats(const co_node *node)
{
	static const co_sync_stats none;

	return node->sync ? &node->sync->stats : &none;
}

int co_od_add_comm_defaults_sync(co_od *od, uint32_t cob_id, uint32_t period_us, uint8_t overflow)
{
	int rc = 0;

	if (!co_od_find(od, SYNC_COB_IDX, 0))
		rc = co_od_add_num(od, SYNC_COB_IDX, 0, CO_T_UNSIGNED32, CO_ACC_RW,
				   cob_id ? cob_id : CO_SYNC_COB_DEFAULT, NULL);
	if (!rc && !co_od_find(od, SYNC_PERIOD_IDX, 0))
		rc = co_od_add_num(od, SYNC_PERIOD_IDX, 0, CO_T_UNSIGNED32, CO_ACC_RW, period_us,
				   NULL);
	if (!rc && !co_od_find(od, SYNC_WINDOW_IDX, 0))
		rc = co_od_add_num(od, SYNC_WINDOW_IDX, 0, CO_T_UNSIGNED32, CO_ACC_RW, 0, NULL);
	if (!rc && !co_od_find(od, SYNC_OVERFLOW_IDX, 0))
		rc = co_od_add_num(od, SYNC_OVERFLOW_IDX, 0, CO_T_UNSIGNED8, CO_ACC_RW, overflow,
				   NULL);
	return rc;
}
