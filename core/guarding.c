/* SPDX-License-Identifier: MIT */
/*
 * Node guarding (master) and life guarding (slave), CiA 301 §7.2.8.3.2.1.
 *
 * Slave: the life time is 100Ch x 100Dh; the timer starts at the first
 * RTR (not at boot), so a slave whose master never guards it never
 * reports a loss. The objects are read on every RTR, so an SDO write of
 * 100Ch/100Dh takes effect with the next RTR; writing 0 stops the timer
 * at once (hook).
 *
 * Master: the node life time (guard time x life factor) runs from the last
 * valid answer; polls go out every guard time independently, so a node
 * that answers late but within its life time is not reported.
 */
#include <errno.h>
#include <stdlib.h>

#include "core/co_internal.h"
#include "core/errctrl.h"
#include "core/guarding.h"
#include "core/heartbeat.h"
#include "core/nmt.h"

#define GUARD_NODES 128u

struct guard_target {
	bool used;
	bool started; /* an answer arrived: toggle known */
	bool failed;
	uint8_t last_toggle;
	uint8_t state;
	uint8_t life_factor;
	uint16_t guard_time_ms;
	int rx;
	uint64_t next_rtr_us;
	uint64_t last_ok_us; /* last valid answer, or start of guarding */
};

struct co_guard {
	/* slave */
	int rx_self;
	uint8_t toggle;
	bool life_active;
	bool life_lost;
	uint64_t life_deadline_us;
	/* master, by node-id */
	struct guard_target t[GUARD_NODES];
};

static void emit(co_node *node, co_event_kind kind, uint8_t remote, uint8_t state, uint8_t prev,
		 uint16_t time_ms)
{
	co_errctrl_emit(node, kind, remote, state, prev, true, time_ms);
}

/* ---- slave ----------------------------------------------------------------- */

static uint64_t life_time_us(const co_node *node)
{
	uint16_t gt = 0;
	uint8_t lf = 0;

	(void)co_od_get_u16(node->od, 0x100C, 0, &gt);
	(void)co_od_get_u8(node->od, 0x100D, 0, &lf);
	return (uint64_t)gt * lf * 1000u;
}

static void slave_rtr(co_node *node, uint64_t now_us)
{
	struct co_guard *g = node->guard;
	uint16_t hb_ms = 0;
	uint64_t life;
	co_frame f;

	(void)co_od_get_u16(node->od, 0x1017, 0, &hb_ms);
	if (hb_ms)
		return; /* heartbeat in use: no guarding (CiA 301 §7.2.8.3.2) */
	if (co_nmt_get_state(node) == CO_NMT_INITIALISING)
		return;
	co_frame_init(&f, CO_NMT_ERRCTRL_BASE + node->node_id, 1);
	f.data[0] = (uint8_t)((co_nmt_get_state(node) & 0x7F) | (g->toggle ? CO_GUARD_TOGGLE : 0));
	g->toggle ^= 1;
	(void)co_node_send(node, &f);

	life = life_time_us(node);
	if (!life) {
		g->life_active = false;
		return;
	}
	g->life_active = true;
	g->life_deadline_us = now_us + life;
	co_node_deadline_lower(node, g->life_deadline_us);
	if (g->life_lost) {
		g->life_lost = false;
		emit(node, CO_EV_GUARD_LIFE_RESUMED, node->node_id, co_nmt_get_state(node),
		     CO_HB_STATE_UNKNOWN, 0);
		co_errctrl_loss_update(node, CO_ERRCTRL_SRC_LIFE_GUARD, false, now_us);
	}
}

static void slave_tick(co_node *node, uint64_t now_us)
{
	struct co_guard *g = node->guard;

	if (!g->life_active || g->life_lost || now_us < g->life_deadline_us)
		return;
	g->life_lost = true;
	g->life_active = false;
	emit(node, CO_EV_GUARD_LIFE_LOST, node->node_id, co_nmt_get_state(node),
	     CO_HB_STATE_UNKNOWN, 0);
	co_errctrl_comm_lost(node, CO_ERRCTRL_SRC_LIFE_GUARD, node->node_id, now_us);
}

static void par_after(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_node *node = ctx;

	(void)e;
	(void)a;
	if (!life_time_us(node))
		node->guard->life_active = false;
}

static const co_od_hooks par_hooks = { .after_write = par_after };

bool co_guard_life_active(const co_node *node)
{
	return node->guard && node->guard->life_active;
}

bool co_guard_life_lost(const co_node *node)
{
	return node->guard && node->guard->life_lost;
}

/* ---- master ---------------------------------------------------------------- */

static void master_answer(co_node *node, struct guard_target *t, uint8_t id, uint8_t byte,
			  uint64_t now_us)
{
	uint8_t toggle = byte >> 7, st = byte & 0x7F;

	if (t->started && toggle == t->last_toggle)
		emit(node, CO_EV_GUARD_TOGGLE, id, st, t->state, t->guard_time_ms);
	t->started = true;
	t->last_toggle = toggle;
	t->last_ok_us = now_us;
	if (t->failed) {
		t->failed = false;
		emit(node, CO_EV_GUARD_RESUMED, id, st, t->state, t->guard_time_ms);
	}
	if (st != t->state)
		emit(node, CO_EV_HB_STATE, id, st, t->state, t->guard_time_ms);
	t->state = st;
}

static void guard_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	struct co_guard *g = node->guard;
	uint8_t id = (uint8_t)(uintptr_t)arg;

	if (id == 0) { /* our own 700h + id: the slave side */
		if (f->flags & CO_FRAME_RTR)
			slave_rtr(node, now_us);
		return;
	}
	if ((f->flags & CO_FRAME_RTR) || f->len < 1 || !g->t[id].used)
		return;
	if (f->data[0] == CO_NMT_INITIALISING) {
		/* Boot-up (heartbeat.c reports it): the node restarts its
		 * toggle at 0, so resynchronise. */
		g->t[id].started = false;
		g->t[id].state = CO_NMT_INITIALISING;
		return;
	}
	master_answer(node, &g->t[id], id, f->data[0], now_us);
}

static void master_rtr(co_node *node, uint8_t id)
{
	co_frame f;

	co_frame_init(&f, CO_NMT_ERRCTRL_BASE + id, 1);
	f.flags = CO_FRAME_RTR;
	(void)co_node_send(node, &f);
}

static uint64_t life_deadline(const struct guard_target *t)
{
	return t->last_ok_us + (uint64_t)t->guard_time_ms * t->life_factor * 1000u;
}

static void master_tick(co_node *node, uint64_t now_us)
{
	struct co_guard *g = node->guard;

	for (unsigned id = 1; id < GUARD_NODES; id++) {
		struct guard_target *t = &g->t[id];
		if (!t->used)
			continue;
		/* Node life time = guard time x life factor since the last
		 * valid answer (or since guarding started). */
		if (!t->failed && now_us >= life_deadline(t)) {
			t->failed = true;
			emit(node, CO_EV_GUARD_FAILED, (uint8_t)id, t->state, t->state,
			     t->guard_time_ms);
		}
		if (now_us < t->next_rtr_us)
			continue;
		master_rtr(node, (uint8_t)id);
		t->next_rtr_us += (uint64_t)t->guard_time_ms * 1000u;
		if (t->next_rtr_us <= now_us)
			t->next_rtr_us = now_us + (uint64_t)t->guard_time_ms * 1000u;
	}
}

int co_guard_master_add(co_node *node, uint8_t target, uint16_t guard_time_ms, uint8_t life_factor,
			uint64_t now_us)
{
	struct co_guard *g = node->guard;
	struct guard_target *t;

	if (!g)
		return -ENODEV;
	if (target < 1 || target > 127 || target == node->node_id || !guard_time_ms)
		return -EINVAL;
	t = &g->t[target];
	if (!t->used) {
		int h = co_rx_register(node, CO_NMT_ERRCTRL_BASE + target, 0, guard_rx,
				       (void *)(uintptr_t)target);
		if (h < 0)
			return h;
		*t = (struct guard_target){ .used = true, .rx = h, .state = CO_HB_STATE_UNKNOWN };
		co_errctrl_guarded_set(node, target, true);
	}
	t->guard_time_ms = guard_time_ms;
	t->life_factor = life_factor ? life_factor : 1;
	node->now_us = now_us;
	t->last_ok_us = now_us;
	t->failed = false;
	master_rtr(node, target);
	t->next_rtr_us = now_us + (uint64_t)guard_time_ms * 1000u;
	co_node_deadline_lower(node, t->next_rtr_us);
	return 0;
}

int co_guard_master_remove(co_node *node, uint8_t target)
{
	struct co_guard *g = node->guard;

	if (!g || target < 1 || target > 127 || !g->t[target].used)
		return -ENOENT;
	(void)co_rx_unregister(node, g->t[target].rx);
	g->t[target].used = false;
	co_errctrl_guarded_set(node, target, false);
	return 0;
}

bool co_guard_master_has(const co_node *node, uint8_t target)
{
	return node->guard && target < GUARD_NODES && node->guard->t[target].used;
}

bool co_guard_master_failed(const co_node *node, uint8_t target)
{
	return co_guard_master_has(node, target) && node->guard->t[target].failed;
}

/* ---- service ------------------------------------------------------------- */

static int guard_init(co_node *node)
{
	struct co_guard *g = calloc(1, sizeof(*g));

	if (!g)
		return -ENOMEM;
	node->guard = g;
	g->rx_self = -1;
	if (node->node_id >= 1 && node->node_id <= 127) {
		g->rx_self = co_rx_register(node, CO_NMT_ERRCTRL_BASE + node->node_id, 0, guard_rx,
					    NULL);
		if (g->rx_self < 0)
			return g->rx_self;
	}
	(void)co_od_set_hooks(node->od, 0x100C, 0, &par_hooks, node);
	(void)co_od_set_hooks(node->od, 0x100D, 0, &par_hooks, node);
	return 0;
}

static void guard_fini(co_node *node)
{
	free(node->guard);
	node->guard = NULL;
}

static uint64_t guard_tick(co_node *node, uint64_t now_us)
{
	struct co_guard *g = node->guard;
	uint64_t next = CO_NO_DEADLINE;

	slave_tick(node, now_us);
	master_tick(node, now_us);
	if (g->life_active && !g->life_lost)
		next = g->life_deadline_us;
	for (unsigned id = 1; id < GUARD_NODES; id++) {
		const struct guard_target *t = &g->t[id];
		if (!t->used)
			continue;
		if (t->next_rtr_us < next)
			next = t->next_rtr_us;
		if (!t->failed && life_deadline(t) < next)
			next = life_deadline(t);
	}
	return next;
}

/* LSS may have changed node->node_id: answer RTRs on the new 700h + id. */
static void slave_follow_id(co_node *node)
{
	struct co_guard *g = node->guard;
	uint8_t id = node->node_id;

	if (id < 1 || id > 127) {
		if (g->rx_self >= 0)
			(void)co_rx_disable(node, g->rx_self);
		return;
	}
	if (g->rx_self < 0)
		g->rx_self = co_rx_register(node, CO_NMT_ERRCTRL_BASE + id, 0, guard_rx, NULL);
	else
		(void)co_rx_move(node, g->rx_self, CO_NMT_ERRCTRL_BASE + id, 0);
}

static void guard_reset_comm(co_node *node, uint64_t now_us)
{
	struct co_guard *g = node->guard;
	bool was_lost = g->life_lost;

	/* The first answer after a reset carries toggle 0 and the life
	 * timer waits for the next RTR (CiA 301 §7.2.8.3.2.1). */
	g->toggle = 0;
	g->life_active = false;
	g->life_lost = false;
	slave_follow_id(node);
	if (was_lost)
		co_errctrl_loss_update(node, CO_ERRCTRL_SRC_LIFE_GUARD, false, now_us);
}

const co_service co_svc_guard = {
	.name = "guarding",
	.init = guard_init,
	.fini = guard_fini,
	.tick = guard_tick,
	.reset_comm = guard_reset_comm,
};

/* ---- standard objects ---------------------------------------------------- */

int co_od_add_comm_defaults_guard(co_od *od)
{
	int rc;

	if (!od)
		return -EINVAL;
	rc = co_od_ensure_num(od, 0x100C, 0, CO_T_UNSIGNED16, CO_ACC_RW, 0, 0);
	if (rc)
		return rc;
	return co_od_ensure_num(od, 0x100D, 0, CO_T_UNSIGNED8, CO_ACC_RW, 0, 0);
}
