/* SPDX-License-Identifier: MIT */
/*
 * Heartbeat producer/consumer and boot-up reception (CiA 301 §7.2.8.3.2.2,
 * §7.2.8.3.2.3, 1016h/1017h).
 *
 * Consumer timing: the deadline of an entry is "last heartbeat + consumer
 * time", an absolute time handed to the line thread as the node deadline,
 * so a loss is reported at that instant (plus the loop's latency), never a
 * tick early; there is no polling period to round to.
 *
 * One receiver per remote node-id, not per consumer entry, because boot-ups
 * must be seen from every node, configured or not (a manager learns about
 * new nodes that way).
 *
 * Each consumer entry is a core/fsm.h machine (co_hb_mon: off, waiting,
 * active, lost): the remote's heartbeat or boot-up is its on_frame, the
 * consumer time its on_timeout. A write of 1016h (or a reset
 * communication) loads the entry again: the machine restarts in off or
 * waiting, which is no transition of the protocol.
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/co_internal.h"
#include "core/errctrl.h"
#include "core/fsm.h"
#include "core/heartbeat.h"
#include "core/nmt.h"
#include "core/sdo.h"

#define HB_NODES 128u   /* index = node-id 1..127 */
#define HB_ENTRIES 127u /* 1016h subs 1..127 */

struct co_hb;

struct hb_entry {
	struct co_hb *hb;
	co_fsm fsm; /* state: co_hb_mon */
	uint8_t node;
	uint16_t time_ms;
	uint64_t deadline_us;
};

struct co_hb {
	co_node *node;
	/* producer */
	uint64_t prod_next_us; /* CO_NO_DEADLINE = off */
	/* consumer */
	struct hb_entry ent[HB_ENTRIES + 1]; /* by 1016h sub, [0] unused */
	uint8_t n_ent;                       /* subs 1..n_ent exist */
	uint8_t last_state[HB_NODES];
	uint64_t last_heard_us[HB_NODES]; /* 0 = never */
	int rx[HB_NODES];
	unsigned lost;
	unsigned rx_missing; /* node-ids not listened to: receiver pool full */
	uint8_t own_id;      /* id whose 700h+id we do not consume (LSS may change it) */
	/* While a remote's frame goes through its entries: its state byte
	 * and the one before (for the events), and whether a loss ended. */
	uint8_t rx_state, rx_prev;
	bool loss_ended;
};

static const co_fsm_def hb_mon_def;

const char *co_hb_mon_to_string(co_hb_mon m)
{
	return co_fsm_state_name(&hb_mon_def, (int)m);
}

static co_hb_mon mon_of(const struct hb_entry *en)
{
	return (co_hb_mon)co_fsm_state_of(&en->fsm);
}

static void emit(co_node *node, co_event_kind kind, uint8_t remote, uint8_t state, uint8_t prev,
		 uint16_t time_ms)
{
	co_errctrl_emit(node, kind, remote, state, prev, false, time_ms);
}

/* ---- producer ------------------------------------------------------------ */

static uint16_t prod_period_ms(const co_node *node)
{
	uint16_t v = 0;

	(void)co_od_get_u16(node->od, 0x1017, 0, &v);
	return v;
}

static void prod_send(co_node *node)
{
	co_frame f;

	co_frame_init(&f, CO_NMT_ERRCTRL_BASE + node->node_id, 1);
	f.data[0] = co_nmt_get_state(node);
	(void)co_node_send(node, &f);
}

static bool prod_allowed(const co_node *node)
{
	return node->node_id >= 1 && node->node_id <= 127 &&
	       co_nmt_get_state(node) != CO_NMT_INITIALISING;
}

/* (Re)start the producer. send_now: a 1017h write sends at once; after a
 * boot-up the boot-up itself was the first heartbeat. */
static void prod_restart(co_node *node, bool send_now, uint64_t now_us)
{
	struct co_hb *ec = node->hb;
	uint16_t ms = prod_period_ms(node);

	ec->prod_next_us = CO_NO_DEADLINE;
	if (!ms || !prod_allowed(node))
		return;
	if (send_now)
		prod_send(node);
	ec->prod_next_us = now_us + (uint64_t)ms * 1000u;
	co_node_deadline_lower(node, ec->prod_next_us);
}

static void prod_tick(co_node *node, uint64_t now_us)
{
	struct co_hb *ec = node->hb;
	uint64_t period;

	if (now_us < ec->prod_next_us)
		return;
	period = (uint64_t)prod_period_ms(node) * 1000u;
	if (!period || !prod_allowed(node)) {
		ec->prod_next_us = CO_NO_DEADLINE;
		return;
	}
	prod_send(node);
	/* Keep the grid (no drift from loop latency) unless we fell behind
	 * by a whole period, then restart from now. */
	ec->prod_next_us += period;
	if (ec->prod_next_us <= now_us)
		ec->prod_next_us = now_us + period;
}

static void p1017_after(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_node *node = ctx;

	(void)e;
	(void)a;
	prod_restart(node, true, node->now_us);
}

static const co_od_hooks p1017_hooks = { .after_write = p1017_after };

int co_hb_producer_set(co_node *node, uint16_t period_ms, uint64_t now_us)
{
	co_od_entry *e = co_od_find(node->od, 0x1017, 0);
	co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL };
	uint8_t buf[2];

	if (!e)
		return -ENOENT;
	if (!node->hb)
		return -ENODEV;
	node->now_us = now_us;
	co_put_le16(buf, period_ms);
	return co_od_write(e, buf, sizeof(buf), &a) ? -EINVAL : 0;
}

/* ---- consumer ------------------------------------------------------------ */

static void ent_load(struct co_hb *ec, uint8_t sub)
{
	struct hb_entry *en = &ec->ent[sub];
	uint32_t v = 0;

	(void)co_od_get_u32(ec->node->od, 0x1016, sub, &v);
	if (mon_of(en) == CO_HB_MON_LOST && ec->lost)
		ec->lost--;
	en->node = (uint8_t)(v >> 16);
	en->time_ms = (uint16_t)v;
	en->deadline_us = CO_NO_DEADLINE;
	co_fsm_init(&en->fsm, &hb_mon_def, en,
		    (en->node && en->node <= 127 && en->time_ms) ? CO_HB_MON_WAITING
								 : CO_HB_MON_OFF);
}

/* Tell core/errctrl.c whether a heartbeat loss remains (it clears EMCY
 * 8130h once neither heartbeat nor life guarding has one). */
static void loss_update(co_node *node, uint64_t now_us)
{
	co_errctrl_loss_update(node, CO_ERRCTRL_SRC_HEARTBEAT, node->hb && node->hb->lost != 0,
			       now_us);
}

/* ---- one consumer entry's machine ----------------------------------------- */

static bool is_bootup(const co_frame *f)
{
	return f->data[0] == CO_NMT_INITIALISING;
}

/* A heartbeat in time: the window starts again. */
static void arm(struct hb_entry *en, uint64_t now_us)
{
	en->deadline_us = now_us + (uint64_t)en->time_ms * 1000u;
	co_node_deadline_lower(en->hb->node, en->deadline_us);
}

/* The first heartbeat (after configuration, a boot-up or a loss). */
static int active_enter(void *obj, uint64_t now_us)
{
	struct hb_entry *en = obj;

	emit(en->hb->node, CO_EV_HB_STARTED, en->node, en->hb->rx_state, en->hb->rx_prev,
	     en->time_ms);
	arm(en, now_us);
	return CO_FSM_STAY;
}

/* A boot-up: wait for the first heartbeat again (a rebooted node's
 * producer may be off until it is configured: no loss). */
static int waiting_enter(void *obj, uint64_t now_us)
{
	struct hb_entry *en = obj;

	(void)now_us;
	en->deadline_us = CO_NO_DEADLINE;
	return CO_FSM_STAY;
}

static int waiting_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	(void)obj;
	(void)now_us;
	return is_bootup(f) ? CO_FSM_STAY : CO_HB_MON_ACTIVE;
}

static int active_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	if (is_bootup(f))
		return CO_HB_MON_WAITING;
	arm(obj, now_us);
	return CO_FSM_STAY;
}

static int active_timeout(void *obj, uint64_t now_us)
{
	(void)obj;
	(void)now_us;
	return CO_HB_MON_LOST;
}

static int lost_enter(void *obj, uint64_t now_us)
{
	struct hb_entry *en = obj;
	struct co_hb *ec = en->hb;

	en->deadline_us = CO_NO_DEADLINE;
	ec->lost++;
	emit(ec->node, CO_EV_HB_LOST, en->node, ec->last_state[en->node], CO_HB_STATE_UNKNOWN,
	     en->time_ms);
	co_errctrl_comm_lost(ec->node, CO_ERRCTRL_SRC_HEARTBEAT, en->node, now_us);
	return CO_FSM_STAY;
}

static int lost_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	(void)obj;
	(void)now_us;
	return is_bootup(f) ? CO_HB_MON_WAITING : CO_HB_MON_ACTIVE;
}

/* Heard from again (heartbeat or boot-up): one loss fewer. */
static void lost_leave(void *obj, uint64_t now_us)
{
	struct hb_entry *en = obj;

	(void)now_us;
	en->hb->lost--;
	en->hb->loss_ended = true;
}

static const co_fsm_state hb_mon_states[] = {
	[CO_HB_MON_OFF] = { .name = "off" },
	[CO_HB_MON_WAITING] = { .name = "waiting",
				.on_enter = waiting_enter,
				.on_frame = waiting_frame },
	[CO_HB_MON_ACTIVE] = { .name = "active",
			       .on_enter = active_enter,
			       .on_frame = active_frame,
			       .on_timeout = active_timeout },
	[CO_HB_MON_LOST] = { .name = "lost",
			     .on_enter = lost_enter,
			     .on_frame = lost_frame,
			     .on_leave = lost_leave },
};

static const co_fsm_def hb_mon_def = {
	.name = "hb_consumer",
	.states = hb_mon_states,
	.n_states = sizeof hb_mon_states / sizeof hb_mon_states[0],
};

static void hb_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	struct co_hb *ec = node->hb;
	uint8_t remote = (uint8_t)(uintptr_t)arg;
	uint8_t st;

	if ((f->flags & CO_FRAME_RTR) || f->len < 1)
		return;
	/* A guarded node's answers carry a toggle bit: guarding reads them.
	 * Its boot-up (00h) is still a boot-up. */
	if (f->data[0] != CO_NMT_INITIALISING && co_errctrl_guarded(node, remote))
		return;
	st = f->data[0] & 0x7F;
	ec->rx_state = st;
	ec->rx_prev = ec->last_state[remote];
	ec->last_state[remote] = st;
	ec->last_heard_us[remote] = now_us ? now_us : 1;
	if (st == CO_NMT_INITIALISING)
		emit(node, CO_EV_BOOTUP, remote, CO_NMT_INITIALISING, ec->rx_prev, 0);
	else if (ec->rx_prev != st)
		emit(node, CO_EV_HB_STATE, remote, st, ec->rx_prev, 0);
	ec->loss_ended = false;
	for (unsigned s = 1; s <= ec->n_ent; s++)
		if (ec->ent[s].node == remote)
			co_fsm_frame(&ec->ent[s].fsm, f, now_us);
	if (ec->loss_ended)
		loss_update(node, now_us);
}

static uint32_t c1016_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct co_hb *ec = ctx;
	uint32_t v;
	uint8_t n;

	if (!a->data || a->size != 4)
		return SDO_AB_TYPE_LEN;
	v = co_get_le32(a->data);
	if (v & 0xFF000000u)
		return SDO_AB_VALUE;
	n = (uint8_t)(v >> 16);
	if (!n || !(uint16_t)v)
		return 0; /* disabling an entry is always fine */
	if (n > 127)
		return SDO_AB_PARAM_INCOMPAT;
	/* CiA 301 §7.5.2.18: one active entry per node. */
	for (unsigned s = 1; s <= ec->n_ent; s++) {
		uint32_t o = 0;
		if (s == e->sub)
			continue;
		(void)co_od_get_u32(ec->node->od, 0x1016, (uint8_t)s, &o);
		if ((uint8_t)(o >> 16) == n && (uint16_t)o)
			return SDO_AB_PARAM_INCOMPAT;
	}
	return 0;
}

static void c1016_after(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct co_hb *ec = ctx;

	(void)a;
	ent_load(ec, e->sub);
	loss_update(ec->node, ec->node->now_us);
}

static const co_od_hooks c1016_hooks = {
	.check_write = c1016_check,
	.after_write = c1016_after,
};

int co_hb_consumer_set(co_node *node, uint8_t remote_id, uint16_t time_ms, uint64_t now_us)
{
	struct co_hb *ec = node->hb;
	co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL };
	unsigned s, free_sub = 0;
	uint8_t buf[4];

	if (!ec)
		return -ENODEV;
	if (remote_id < 1 || remote_id > 127)
		return -EINVAL;
	if (!ec->n_ent)
		return -ENOENT;
	for (s = 1; s <= ec->n_ent; s++) {
		uint32_t v = 0;
		(void)co_od_get_u32(node->od, 0x1016, (uint8_t)s, &v);
		if ((uint8_t)(v >> 16) == remote_id)
			break;
		if (!free_sub && (!(uint8_t)(v >> 16) || !(uint16_t)v))
			free_sub = s;
	}
	if (s > ec->n_ent) {
		if (!free_sub)
			return -ENOSPC;
		s = free_sub;
	}
	node->now_us = now_us;
	co_put_le32(buf, ((uint32_t)remote_id << 16) | time_ms);
	return co_od_write(co_od_find(node->od, 0x1016, (uint8_t)s), buf, 4, &a) ? -EINVAL : 0;
}

co_hb_mon co_hb_consumer_status(const co_node *node, uint8_t remote_id)
{
	const struct co_hb *ec = node->hb;

	if (!ec)
		return CO_HB_MON_OFF;
	for (unsigned s = 1; s <= ec->n_ent; s++)
		if (ec->ent[s].node == remote_id && mon_of(&ec->ent[s]) != CO_HB_MON_OFF)
			return mon_of(&ec->ent[s]);
	return CO_HB_MON_OFF;
}

void co_hb_lost_nodes(const co_node *node, uint64_t lost[2])
{
	const struct co_hb *ec = node->hb;

	lost[0] = lost[1] = 0;
	for (unsigned s = 1; ec && s <= ec->n_ent; s++) {
		uint8_t n = ec->ent[s].node;
		if (n >= 1 && n <= 127 && mon_of(&ec->ent[s]) == CO_HB_MON_LOST)
			lost[n / 64u] |= 1ull << (n % 64u);
	}
}

uint8_t co_hb_remote_state(const co_node *node, uint8_t remote_id)
{
	if (!node->hb || remote_id >= HB_NODES)
		return CO_HB_STATE_UNKNOWN;
	return node->hb->last_state[remote_id];
}

uint64_t co_hb_last_heard_us(const co_node *node, uint8_t remote_id)
{
	if (!node->hb || remote_id >= HB_NODES)
		return 0;
	return node->hb->last_heard_us[remote_id];
}

unsigned co_hb_lost_count(const co_node *node)
{
	return node->hb ? node->hb->lost : 0;
}

/* ---- service ------------------------------------------------------------- */

static void load_all(struct co_hb *ec)
{
	ec->lost = 0;
	for (unsigned s = 1; s <= ec->n_ent; s++) {
		co_fsm_init(&ec->ent[s].fsm, &hb_mon_def, &ec->ent[s], CO_HB_MON_OFF);
		ent_load(ec, (uint8_t)s);
	}
}

static int hb_init(co_node *node)
{
	struct co_hb *ec = calloc(1, sizeof(*ec));
	co_od_entry *e;

	if (!ec)
		return -ENOMEM;
	node->hb = ec;
	ec->node = node;
	ec->prod_next_us = CO_NO_DEADLINE;
	for (unsigned s = 0; s <= HB_ENTRIES; s++) {
		ec->ent[s].hb = ec;
		co_fsm_init(&ec->ent[s].fsm, &hb_mon_def, &ec->ent[s], CO_HB_MON_OFF);
	}
	memset(ec->last_state, CO_HB_STATE_UNKNOWN, sizeof(ec->last_state));
	for (unsigned n = 0; n < HB_NODES; n++)
		ec->rx[n] = -1;

	if ((e = co_od_find(node->od, 0x1017, 0)) != NULL)
		co_od_entry_set_hooks(e, &p1017_hooks, node);
	while (ec->n_ent < HB_ENTRIES &&
	       (e = co_od_find(node->od, 0x1016, (uint8_t)(ec->n_ent + 1)))) {
		co_od_entry_set_hooks(e, &c1016_hooks, ec);
		ec->n_ent++;
	}
	load_all(ec);

	ec->own_id = node->node_id;
	for (unsigned n = 1; n <= 127; n++) {
		if (n == node->node_id)
			continue;
		ec->rx[n] = co_rx_register(node, CO_NMT_ERRCTRL_BASE + n, 0, hb_rx,
					   (void *)(uintptr_t)n);
		/* A node built with a small receiver pool (rx_max) still
		 * works: it just does not see the remaining node-ids. */
		if (ec->rx[n] == -ENOSPC) {
			ec->rx[n] = -1;
			ec->rx_missing++;
		} else if (ec->rx[n] < 0) {
			return ec->rx[n];
		}
	}
	return 0;
}

static void hb_fini(co_node *node)
{
	free(node->hb);
	node->hb = NULL;
}

static uint64_t hb_tick(co_node *node, uint64_t now_us)
{
	struct co_hb *ec = node->hb;
	uint64_t next;

	prod_tick(node, now_us);
	for (unsigned s = 1; s <= ec->n_ent; s++) {
		struct hb_entry *en = &ec->ent[s];
		if (mon_of(en) == CO_HB_MON_ACTIVE && now_us >= en->deadline_us)
			co_fsm_timeout(&en->fsm, now_us);
	}
	/* A loss may have changed the NMT state and the producer with it. */
	next = ec->prod_next_us;
	for (unsigned s = 1; s <= ec->n_ent; s++)
		if (mon_of(&ec->ent[s]) == CO_HB_MON_ACTIVE && ec->ent[s].deadline_us < next)
			next = ec->ent[s].deadline_us;
	return next;
}

/* LSS gave us another node-ID (active from this reset communication on):
 * listen to the old one, stop listening to our own. */
static void own_id_changed(co_node *node)
{
	struct co_hb *ec = node->hb;
	uint8_t old = ec->own_id, now = node->node_id;

	if (old >= 1 && old <= 127 && ec->rx[old] < 0)
		ec->rx[old] = co_rx_register(node, CO_NMT_ERRCTRL_BASE + old, 0, hb_rx,
					     (void *)(uintptr_t)old);
	if (now >= 1 && now <= 127 && ec->rx[now] >= 0) {
		(void)co_rx_unregister(node, ec->rx[now]);
		ec->rx[now] = -1;
	}
	ec->own_id = now;
}

static void hb_reset_comm(co_node *node, uint64_t now_us)
{
	struct co_hb *ec = node->hb;
	bool had_loss = ec->lost != 0;

	ec->prod_next_us = CO_NO_DEADLINE; /* restarts after the boot-up */
	if (node->node_id != ec->own_id)
		own_id_changed(node);
	load_all(ec);
	if (had_loss)
		loss_update(node, now_us);
}

static void hb_nmt_changed(co_node *node, uint8_t state, uint64_t now_us)
{
	struct co_hb *ec = node->hb;

	if (state == CO_NMT_INITIALISING)
		ec->prod_next_us = CO_NO_DEADLINE;
	else if (ec->prod_next_us == CO_NO_DEADLINE)
		prod_restart(node, false, now_us); /* after the boot-up */
}

const co_service co_svc_hb = {
	.name = "heartbeat",
	.init = hb_init,
	.fini = hb_fini,
	.tick = hb_tick,
	.reset_comm = hb_reset_comm,
	.nmt_changed = hb_nmt_changed,
};

/* ---- standard objects ---------------------------------------------------- */

int co_od_add_comm_defaults_hb(co_od *od, uint8_t consumers, uint16_t producer_ms)
{
	int rc;

	if (!od || consumers > HB_ENTRIES)
		return -EINVAL;
	if (consumers && !co_od_has_index(od, 0x1016)) {
		if ((rc = co_od_add_array(od, 0x1016, CO_T_UNSIGNED32, consumers, CO_ACC_RW, 0)))
			return rc;
	}
	return co_od_ensure_num(od, 0x1017, 0, CO_T_UNSIGNED16, CO_ACC_RW, producer_ms, 0);
}
