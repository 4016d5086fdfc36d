/* SPDX-License-Identifier: MIT */
/*
 * PDO service: RPDO reception, TPDO transmission, the comm/mapping record
 * hooks (CiA 301 §7.2.2, §7.5.2.35..38). Mapping validation, compilation
 * and the OD builder live in pdo_map.c; this file is the runtime.
 *
 * Why the shapes below:
 * - All PDOs sit in one array allocated at init (RPDOs first, then
 *   TPDOs); slot[dir][nr-1] maps a PDO number to its place. Mapping items
 *   come from one pool sized by the mapping subs present in the OD.
 * - Receive dispatch is the node's O(1) table: each PDO registers its own
 *   receiver with itself as argument, so a frame reaches its PDO with no
 *   lookup at all.
 * - Timers: each PDO has at most one pending deadline (event timer or RPDO
 *   deadline, or the end of the inhibit time when an event waits), kept in
 *   a binary min-heap indexed by PDO with a back-pointer (hpos). Arming,
 *   moving and cancelling are O(log n), the next deadline is O(1). A cached
 *   minimum alone would need an O(n) rescan each time the earliest PDO
 *   fires; with 512 event-timer TPDOs that is a rescan per frame sent.
 * - SYNC work walks a compact list of the synchronous PDOs (rebuilt only
 *   after a configuration change), not all 1024.
 * - co_pdo_object_changed() uses a sorted (object -> TPDO) index, rebuilt
 *   lazily after mapping changes; mappings change rarely, events often.
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/co_internal.h"
#include "core/emcy.h"
#include "core/nmt.h"
#include "core/pdo.h"
#include "core/pdo_map.h"
#include "core/sync.h"

#define HEAP_NONE 0xFFFFu

/* ---- small helpers --------------------------------------------------------- */

const char *co_pdo_tt_to_string(uint8_t tt)
{
	if (tt == CO_PDO_TT_SYNC_ACYCLIC)
		return "sync-acyclic";
	if (tt <= CO_PDO_TT_SYNC_MAX)
		return "sync-cyclic";
	switch (tt) {
	case CO_PDO_TT_RTR_SYNC:
		return "rtr-sync";
	case CO_PDO_TT_RTR_EVENT:
		return "rtr-event";
	case CO_PDO_TT_EVENT_MANUF:
		return "event-manufacturer";
	case CO_PDO_TT_EVENT_PROFILE:
		return "event-profile";
	default:
		return "reserved";
	}
}

const char *co_pdo_dir_to_string(co_pdo_dir d)
{
	return d == CO_PDO_TX ? "tpdo" : "rpdo";
}

static bool tt_is_sync(uint8_t tt)
{
	return tt <= CO_PDO_TT_SYNC_MAX;
}

static bool tt_is_event(uint8_t tt)
{
	return tt >= CO_PDO_TT_EVENT_MANUF;
}

static uint16_t pdo_pos(const struct co_pdo *P, const struct pdo *p)
{
	return (uint16_t)(p - P->v);
}

/* ---- timer heap ------------------------------------------------------------- */

static uint64_t pdo_due(const struct pdo *p)
{
	uint64_t d = p->timer_us;

	if (p->event_pending && p->inhibit_until < d)
		d = p->inhibit_until;
	return d;
}

static void heap_set(struct co_pdo *P, uint16_t i, uint16_t k)
{
	P->heap[i] = k;
	P->v[k].hpos = i;
}

static void heap_up(struct co_pdo *P, uint16_t i)
{
	uint16_t k = P->heap[i];

	while (i > 0) {
		uint16_t parent = (uint16_t)((i - 1) / 2);
		if (P->v[P->heap[parent]].due <= P->v[k].due)
			break;
		heap_set(P, i, P->heap[parent]);
		i = parent;
	}
	heap_set(P, i, k);
}

static void heap_down(struct co_pdo *P, uint16_t i)
{
	uint16_t k = P->heap[i];

	for (;;) {
		uint32_t l = 2u * i + 1, r = l + 1, m = l;
		if (l >= P->heap_n)
			break;
		if (r < P->heap_n && P->v[P->heap[r]].due < P->v[P->heap[l]].due)
			m = r;
		if (P->v[k].due <= P->v[P->heap[m]].due)
			break;
		heap_set(P, i, P->heap[m]);
		i = (uint16_t)m;
	}
	heap_set(P, i, k);
}

static void heap_remove(struct co_pdo *P, struct pdo *p)
{
	uint16_t i = p->hpos, last;

	if (i == HEAP_NONE)
		return;
	p->hpos = HEAP_NONE;
	last = P->heap[--P->heap_n];
	if (i == P->heap_n)
		return;
	heap_set(P, i, last);
	heap_up(P, i);
	heap_down(P, P->v[last].hpos);
}

/* Put p where its current due time says (or take it out). */
static void heap_update(struct co_pdo *P, struct pdo *p)
{
	uint64_t d = pdo_due(p);

	if (d == CO_NO_DEADLINE) {
		heap_remove(P, p);
		return;
	}
	p->due = d;
	if (p->hpos == HEAP_NONE) {
		P->heap[P->heap_n] = pdo_pos(P, p);
		p->hpos = P->heap_n++;
		heap_up(P, p->hpos);
	} else {
		heap_up(P, p->hpos);
		heap_down(P, p->hpos);
	}
	co_node_deadline_lower(P->node, d);
}

/* ---- runtime state ------------------------------------------------------------ */

/* The EMCY of each supervision fault, in CO_PDO_FAULT_* bit order. */
static const uint16_t fault_emcy[CO_PDO_FAULT_KINDS] = {
	CO_EMCY_RPDO_TIMEOUT,
	CO_EMCY_PDO_LENGTH,
	CO_EMCY_PDO_LENGTH_HIGH,
};

static void rpdo_emit(struct co_pdo *P, const struct pdo *p, co_event_kind k, const uint8_t *data,
		      uint8_t len, uint8_t fault);

/* A supervision episode begins: its EMCY once (CiA 301 §7.2.7: an error
 * is signalled when it occurs, not per frame; 1015h would only queue
 * copies that tell nothing new), manufacturer bytes 0..1 = RPDO number. */
static void fault_begin(struct co_pdo *P, struct pdo *p, uint8_t fault, uint64_t now_us)
{
	uint8_t msef[5] = { (uint8_t)p->nr, (uint8_t)(p->nr >> 8), 0, 0, 0 };
	unsigned k = (unsigned)__builtin_ctz(fault);

	p->faults |= fault;
	P->fault_count[k]++;
	co_emcy_send(P->node, fault_emcy[k], CO_EMCY_REG_COMM, msef, now_us);
}

/* End the episodes in `which` that p has open. An error code leaves the
 * active list (co_emcy_clear: the error-reset EMCY once none is left) only
 * when no other RPDO has it open too. Reports the end with `len` = the
 * frame that ended it (0: a reconfiguration did). */
static void faults_end(struct co_pdo *P, struct pdo *p, uint8_t which, uint8_t len, uint64_t now_us)
{
	uint8_t ended = p->faults & which;

	if (!ended)
		return;
	p->faults &= (uint8_t)~ended;
	for (unsigned k = 0; k < CO_PDO_FAULT_KINDS; k++)
		if ((ended & (1u << k)) && --P->fault_count[k] == 0)
			co_emcy_clear(P->node, fault_emcy[k], now_us);
	rpdo_emit(P, p, CO_EV_RPDO_RECOVERED, NULL, len, ended);
}

/* Start p afresh: on entering OPERATIONAL, after a configuration change,
 * and (with operational false) to stop it. */
static void pdo_runtime_reset(struct co_pdo *P, struct pdo *p, uint64_t now_us)
{
	p->pending = false;
	p->sampled = false;
	p->event_pending = false;
	p->sync_cnt = 0;
	p->inhibit_until = 0;
	p->buf_len = 0;
	p->wait_start = p->dir == CO_PDO_TX && p->sync_start && p->tt >= CO_PDO_TT_SYNC_MIN &&
			p->tt <= CO_PDO_TT_SYNC_MAX;
	p->timer_us = CO_NO_DEADLINE;
	if (P->operational && p->valid && p->dir == CO_PDO_TX && tt_is_event(p->tt) && p->event_ms)
		p->timer_us = now_us + (uint64_t)p->event_ms * 1000u;
	heap_update(P, p);
	if (P->gate && p->dir == CO_PDO_TX)
		(void)P->gate(P->gate_ctx, p->nr, CO_PDO_GATE_RESET, now_us);
}

/* Re-read the communication record into p. */
static void pdo_load_comm(struct pdo *p)
{
	p->cob = p->e_comm[1] ? (uint32_t)co_od_entry_raw(p->e_comm[1]) : CO_PDO_COB_INVALID;
	p->tt = p->e_comm[2] ? (uint8_t)co_od_entry_raw(p->e_comm[2]) : CO_PDO_TT_EVENT_PROFILE;
	p->inhibit_100us = p->e_comm[3] ? (uint16_t)co_od_entry_raw(p->e_comm[3]) : 0;
	p->event_ms = p->e_comm[5] ? (uint16_t)co_od_entry_raw(p->e_comm[5]) : 0;
	p->sync_start = p->e_comm[6] ? (uint8_t)co_od_entry_raw(p->e_comm[6]) : 0;
}

/* Apply the loaded configuration: validity, receiver, runtime. */
static void pdo_reconfigure(struct co_pdo *P, struct pdo *p, uint64_t now_us)
{
	uint32_t id;
	uint8_t flags;
	bool listen;

	p->valid = !(p->cob & CO_PDO_COB_INVALID) && p->map_ok;
	listen = p->valid && (p->dir == CO_PDO_RX || !(p->cob & CO_PDO_COB_NO_RTR));
	co_cob_split(p->cob, &id, &flags);
	if (p->rx_h >= 0) {
		if (listen)
			co_rx_move(P->node, p->rx_h, id, flags);
		else
			co_rx_disable(P->node, p->rx_h);
	}
	if (!p->valid)
		faults_end(P, p, p->faults, 0, now_us);
	P->sync_dirty = true;
	pdo_runtime_reset(P, p, now_us);
}

/* ---- TPDO ------------------------------------------------------------------- */

static void tpdo_frame(const struct pdo *p, co_frame *f)
{
	uint32_t id;
	uint8_t flags;

	co_cob_split(p->cob, &id, &flags);
	co_frame_init(f, id, p->len);
	f->flags = flags;
}

/* Send p: fresh sample, or the SYNC sample in buf (TT 252). Every
 * transmission starts the inhibit time and restarts the event timer. */
static void tpdo_send(struct co_pdo *P, struct pdo *p, bool from_buf, uint64_t now_us)
{
	co_frame f;

	tpdo_frame(p, &f);
	if (from_buf)
		memcpy(f.data, p->buf, p->len);
	else
		pdo_map_pack(p, f.data);
	if (co_node_send(P->node, &f) == 0)
		P->stats.tx++;
	else
		P->stats.tx_failed++;
	p->inhibit_until = now_us + (uint64_t)p->inhibit_100us * 100u;
	p->event_pending = false;
	if (tt_is_event(p->tt))
		p->timer_us = p->event_ms ? now_us + (uint64_t)p->event_ms * 1000u : CO_NO_DEADLINE;
	heap_update(P, p);
}

static void tpdo_wait(struct co_pdo *P, struct pdo *p)
{
	if (!p->event_pending)
		P->stats.tx_inhibited++;
	p->event_pending = true;
	heap_update(P, p);
}

/* An event for an event-driven TPDO: send now, or once the inhibit time
 * has elapsed (CiA 301 §7.2.2.5: the inhibit time is a minimum interval).
 * With a second sender (co_pdo_set_tx_gate) its transmissions count too. */
static void tpdo_trigger(struct co_pdo *P, struct pdo *p, uint64_t now_us)
{
	uint64_t until;

	if (now_us < p->inhibit_until) {
		if (P->gate &&
		    P->gate(P->gate_ctx, p->nr, CO_PDO_GATE_WAIT, now_us) == CO_PDO_GATE_SERVED)
			return;
		tpdo_wait(P, p);
		return;
	}
	until = P->gate ? P->gate(P->gate_ctx, p->nr, CO_PDO_GATE_CLAIM, now_us) : CO_PDO_GATE_GO;
	if (until == CO_PDO_GATE_SERVED)
		return;
	if (until != CO_PDO_GATE_GO) {
		p->inhibit_until = until;
		tpdo_wait(P, p);
		return;
	}
	tpdo_send(P, p, false, now_us);
}

/* A transmission that does not wait for the inhibit time (RTR, SYNC). */
static void tpdo_send_forced(struct co_pdo *P, struct pdo *p, bool from_buf, uint64_t now_us)
{
	if (P->gate)
		(void)P->gate(P->gate_ctx, p->nr, CO_PDO_GATE_FORCED, now_us);
	tpdo_send(P, p, from_buf, now_us);
}

static void tpdo_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	struct pdo *p = arg;
	struct co_pdo *P = node->pdo;

	if (!(f->flags & CO_FRAME_RTR))
		return; /* data on our own TPDO id: not for us */
	if (!P->operational || !p->valid || (p->cob & CO_PDO_COB_NO_RTR)) {
		P->stats.rx_ignored++;
		return;
	}
	P->stats.rtr++;
	tpdo_send_forced(P, p, p->tt == CO_PDO_TT_RTR_SYNC && p->sampled, now_us);
}

/* ---- RPDO ------------------------------------------------------------------- */

static void rpdo_emit(struct co_pdo *P, const struct pdo *p, co_event_kind k, const uint8_t *data,
		      uint8_t len, uint8_t fault)
{
	co_event ev = { .kind = k };
	uint32_t id;

	co_cob_split(p->cob, &id, &ev.u.pdo.flags);
	ev.u.pdo.nr = p->nr;
	ev.u.pdo.cob_id = id;
	ev.u.pdo.len = len;
	ev.u.pdo.mapped_len = p->len;
	ev.u.pdo.fault = fault;
	ev.u.pdo.event_ms = p->event_ms;
	if (data && len)
		memcpy(ev.u.pdo.data, data, len > 8 ? 8 : len);
	ev.u.pdo.n_map = p->n;
	ev.u.pdo.map = p->evmap;
	co_node_emit(P->node, &ev);
}

static void rpdo_commit(struct co_pdo *P, struct pdo *p, const uint8_t *data, uint8_t len)
{
	uint8_t n = p->n;

	for (uint8_t i = 0; i < n; i++) {
		uint32_t ab = pdo_map_unpack_one(p, i, data, len);
		co_event ev = { .kind = CO_EV_RPDO_OBJECT };

		if (!p->items[i].e)
			continue; /* dummy */
		if (ab)
			P->stats.od_refused++;
		ev.u.pdo_obj.nr = p->nr;
		ev.u.pdo_obj.index = p->evmap[i].index;
		ev.u.pdo_obj.sub = p->evmap[i].sub;
		ev.u.pdo_obj.bits = p->evmap[i].bits;
		ev.u.pdo_obj.abort = ab;
		co_node_emit(P->node, &ev);
		if (!p->valid)
			return; /* a hook or callback reconfigured it */
	}
	rpdo_emit(P, p, CO_EV_RPDO, data, len, 0);
}

/* CiA 301 §7.5.2.36: a frame shorter than the mapping is not processed
 * (EMCY 8210h "PDO not processed due to length error"); of a longer one
 * the leading bytes the mapping covers are used (EMCY 8220h "PDO length
 * exceeded"). Either begins an episode unless one of that kind is open;
 * a short frame ends a "long" episode and the other way round. */
static void rpdo_length_error(struct co_pdo *P, struct pdo *p, const co_frame *f, uint64_t now_us)
{
	uint8_t fault = f->len < p->len ? CO_PDO_FAULT_SHORT : CO_PDO_FAULT_LONG;

	P->stats.rx_length++;
	if (p->faults & fault)
		return;
	/* the new error first: ending the other one must not look like
	 * "no error left" (an error-reset EMCY between the two) */
	fault_begin(P, p, fault, now_us);
	faults_end(P, p, (CO_PDO_FAULT_SHORT | CO_PDO_FAULT_LONG) & ~fault, f->len, now_us);
	rpdo_emit(P, p, CO_EV_RPDO_LENGTH, f->data, f->len, fault);
}

static void rpdo_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	struct pdo *p = arg;
	struct co_pdo *P = node->pdo;

	if (f->flags & CO_FRAME_RTR)
		return; /* a request to the producer, not data */
	if (!P->operational || !p->valid) {
		P->stats.rx_ignored++;
		return;
	}
	if (f->len != p->len) {
		rpdo_length_error(P, p, f, now_us);
		if (f->len < p->len)
			return;
	}
	if (tt_is_sync(p->tt) && !co_sync_in_window(node, now_us)) {
		P->stats.rx_late++;
		return;
	}
	/* the deadline is met by data that is used, whatever its length */
	faults_end(P, p, f->len == p->len ? p->faults : CO_PDO_FAULT_TIMEOUT, f->len, now_us);
	if (!p->valid)
		return; /* a hook reconfigured it */
	P->stats.rx++;
	if (p->event_ms) {
		p->timer_us = now_us + (uint64_t)p->event_ms * 1000u;
		heap_update(P, p);
	}
	if (tt_is_sync(p->tt)) {
		memcpy(p->buf, f->data, p->len);
		p->buf_len = p->len;
		p->pending = true;
		return;
	}
	rpdo_commit(P, p, f->data, p->len);
}

/* ---- SYNC ------------------------------------------------------------------- */

static void sync_list_rebuild(struct co_pdo *P)
{
	P->sync_n = 0;
	for (uint16_t k = 0; k < P->n_rx + P->n_tx; k++) {
		const struct pdo *p = &P->v[k];
		if (p->valid &&
		    (tt_is_sync(p->tt) || (p->dir == CO_PDO_TX && p->tt == CO_PDO_TT_RTR_SYNC)))
			P->sync_list[P->sync_n++] = k;
	}
	P->sync_dirty = false;
}

static void tpdo_sync(struct co_pdo *P, struct pdo *p, uint8_t counter, uint64_t now_us)
{
	if (p->tt == CO_PDO_TT_RTR_SYNC) {
		pdo_map_pack(p, p->buf);
		p->buf_len = p->len;
		p->sampled = true;
		return;
	}
	if (p->tt == CO_PDO_TT_SYNC_ACYCLIC) {
		if (p->pending) {
			p->pending = false;
			tpdo_send_forced(P, p, false, now_us);
		}
		return;
	}
	if (p->wait_start) {
		/* CiA 301 §7.5.2.35 sub 6: the SYNC whose counter equals the
		 * start value is the first one; no counter, no start value. */
		if (counter != 0) {
			if (counter != p->sync_start)
				return;
			p->wait_start = false;
			p->sync_cnt = 0;
			tpdo_send_forced(P, p, false, now_us);
			return;
		}
		p->wait_start = false;
	}
	if (++p->sync_cnt >= p->tt) {
		p->sync_cnt = 0;
		tpdo_send_forced(P, p, false, now_us);
	}
}

void co_pdo_sync_ind(co_node *node, uint8_t counter, uint64_t now_us)
{
	struct co_pdo *P = node->pdo;

	if (!P || !P->operational)
		return;
	if (P->sync_dirty)
		sync_list_rebuild(P);
	/* RPDOs first: a device acting on received set-points and then
	 * reporting actual values at the same SYNC sees the new ones. */
	for (uint16_t i = 0; i < P->sync_n; i++) {
		struct pdo *p = &P->v[P->sync_list[i]];
		if (p->dir == CO_PDO_RX && p->valid && p->pending) {
			p->pending = false;
			rpdo_commit(P, p, p->buf, p->buf_len);
		}
	}
	for (uint16_t i = 0; i < P->sync_n; i++) {
		struct pdo *p = &P->v[P->sync_list[i]];
		if (p->dir == CO_PDO_TX && p->valid && P->operational)
			tpdo_sync(P, p, counter, now_us);
	}
}

/* ---- timers ------------------------------------------------------------------ */

static void pdo_expired(struct co_pdo *P, struct pdo *p, uint64_t now_us)
{
	bool fire = false;

	if (p->dir == CO_PDO_RX) {
		/* deadline missed; re-armed by the next frame used, so this
		 * runs once per episode */
		p->timer_us = CO_NO_DEADLINE;
		heap_update(P, p);
		P->stats.rx_timeout++;
		if (!(p->faults & CO_PDO_FAULT_TIMEOUT))
			fault_begin(P, p, CO_PDO_FAULT_TIMEOUT, now_us);
		rpdo_emit(P, p, CO_EV_RPDO_TIMEOUT, NULL, 0, CO_PDO_FAULT_TIMEOUT);
		return;
	}
	if (p->timer_us <= now_us) {
		p->timer_us = CO_NO_DEADLINE; /* restarted by the send */
		fire = true;
	}
	if (p->event_pending && p->inhibit_until <= now_us)
		fire = true;
	if (fire)
		tpdo_trigger(P, p, now_us);
	else
		heap_update(P, p);
}

static uint64_t pdo_tick(co_node *node, uint64_t now_us)
{
	struct co_pdo *P = node->pdo;

	if (!P)
		return CO_NO_DEADLINE;
	while (P->heap_n && P->v[P->heap[0]].due <= now_us)
		pdo_expired(P, &P->v[P->heap[0]], now_us);
	return P->heap_n ? P->v[P->heap[0]].due : CO_NO_DEADLINE;
}

/* ---- OD hooks ------------------------------------------------------------------ */

static uint32_t check_cob(const struct pdo *p, uint32_t v)
{
	const uint32_t id_bits = CO_PDO_COB_EXT | CO_FRAME_EFF_MASK;

	/* CiA 301 §7.5.2.35: bits 0..29 only while the PDO does not exist */
	if (!(p->cob & CO_PDO_COB_INVALID) && !(v & CO_PDO_COB_INVALID) &&
	    (v & id_bits) != (p->cob & id_bits))
		return SDO_AB_VALUE;
	if (v & CO_PDO_COB_INVALID)
		return 0;
	if (!(v & CO_PDO_COB_EXT) && ((v & CO_FRAME_EFF_MASK & ~CO_FRAME_SFF_MASK) ||
				      co_cob_is_restricted(v & CO_FRAME_SFF_MASK)))
		return SDO_AB_VALUE;
	if (!p->map_ok)
		return CO_PDO_AB_SEQUENCE; /* mapping broken: fix it first */
	return 0;
}

static uint32_t check_comm(struct pdo *p, uint8_t sub, const uint8_t *d)
{
	bool valid = !(p->cob & CO_PDO_COB_INVALID);

	switch (sub) {
	case 1:
		return check_cob(p, co_get_le32(d));
	case 2:
		if (d[0] <= CO_PDO_TT_SYNC_MAX || d[0] >= CO_PDO_TT_EVENT_MANUF)
			return 0;
		if (p->dir == CO_PDO_TX && d[0] >= CO_PDO_TT_RTR_SYNC)
			return 0;
		return SDO_AB_VALUE;
	case 3:
		return p->dir == CO_PDO_TX && valid ? SDO_AB_VALUE : 0;
	case 6:
		return valid ? SDO_AB_VALUE : 0;
	default:
		return 0;
	}
}

static uint32_t pdo_check_write(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct co_pdo *P = ctx;
	bool is_map;
	struct pdo *p = pdo_of_index(P, e->index, &is_map);

	if (!p || !a->data)
		return SDO_AB_GENERAL;
	if (!is_map)
		return check_comm(p, e->sub, a->data);
	if (e->sub == 0)
		return pdo_map_check_count(P, p, a->data[0]);
	return pdo_map_check_entry(P, p, co_get_le32(a->data));
}

static void pdo_after_write(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct co_pdo *P = ctx;
	uint64_t now_us = P->node->now_us;
	bool is_map;
	struct pdo *p = pdo_of_index(P, e->index, &is_map);

	(void)a;
	if (!p)
		return;
	if (is_map) {
		if (e->sub != 0)
			return; /* entries take effect with sub 0 = n */
		pdo_map_compile(P, p);
		pdo_reconfigure(P, p, now_us);
		return;
	}
	pdo_load_comm(p);
	if (e->sub == 5) {
		/* a new event time applies from now on, nothing else moves */
		if (p->dir == CO_PDO_TX && P->operational && p->valid && tt_is_event(p->tt))
			p->timer_us = p->event_ms ? now_us + (uint64_t)p->event_ms * 1000u
						  : CO_NO_DEADLINE;
		else if (p->dir == CO_PDO_RX && !p->event_ms)
			p->timer_us = CO_NO_DEADLINE;
		heap_update(P, p);
		return;
	}
	pdo_reconfigure(P, p, now_us);
}

static const co_od_hooks pdo_hooks = {
	.check_write = pdo_check_write,
	.after_write = pdo_after_write,
};

/* ---- service ops ------------------------------------------------------------------ */

static void pdo_hooks_set(struct co_pdo *P, const co_od_hooks *h)
{
	for (uint16_t k = 0; k < P->n_rx + P->n_tx; k++) {
		struct pdo *p = &P->v[k];
		for (int s = 1; s <= 6; s++)
			if (p->e_comm[s])
				co_od_entry_set_hooks(p->e_comm[s], h, h ? P : NULL);
		if (p->e_map0)
			co_od_entry_set_hooks(p->e_map0, h, h ? P : NULL);
		for (uint8_t i = 0; i < p->cap; i++)
			co_od_entry_set_hooks(p->e_map[i], h, h ? P : NULL);
	}
}

static void pdo_load_all(struct co_pdo *P, uint64_t now_us)
{
	for (uint16_t k = 0; k < P->n_rx + P->n_tx; k++) {
		struct pdo *p = &P->v[k];
		/* the configuration the episodes were about is gone */
		faults_end(P, p, p->faults, 0, now_us);
		pdo_load_comm(p);
		if (!pdo_map_compile(P, p))
			P->stats.map_errors++;
		pdo_reconfigure(P, p, now_us);
	}
}

static void pdo_sync_observer(co_node *node, void *ctx, uint8_t counter, uint64_t now_us)
{
	(void)ctx;
	co_pdo_sync_ind(node, counter, now_us);
}

static int pdo_init(co_node *node)
{
	struct co_pdo *P = calloc(1, sizeof(*P));
	int rc;

	if (!P)
		return -ENOMEM;
	node->pdo = P;
	P->node = node;
	P->operational = co_nmt_get_state(node) == CO_NMT_OPERATIONAL;
	rc = pdo_map_alloc(P);
	if (rc)
		return rc;
	for (uint16_t k = 0; k < P->n_rx + P->n_tx; k++) {
		struct pdo *p = &P->v[k];
		int h = co_rx_register(node, 0, 0, p->dir == CO_PDO_RX ? rpdo_rx : tpdo_rx, p);
		if (h < 0)
			return h;
		p->rx_h = h;
		co_rx_disable(node, h);
	}
	pdo_hooks_set(P, &pdo_hooks);
	pdo_load_all(P, node->now_us);
	return co_sync_observer_add(node, pdo_sync_observer, NULL);
}

static void pdo_fini(co_node *node)
{
	struct co_pdo *P = node->pdo;

	if (!P)
		return;
	if (P->v) {
		/* the OD outlives the node: leave no hook pointing here */
		pdo_hooks_set(P, NULL);
		for (uint16_t k = 0; k < P->n_rx + P->n_tx; k++)
			if (P->v[k].rx_h >= 0)
				co_rx_unregister(node, P->v[k].rx_h);
	}
	pdo_map_free(P);
	free(P);
	node->pdo = NULL;
}

static void pdo_reset_comm(co_node *node, uint64_t now_us)
{
	struct co_pdo *P = node->pdo;

	if (P)
		pdo_load_all(P, now_us);
}

static void pdo_nmt_changed(co_node *node, uint8_t state, uint64_t now_us)
{
	struct co_pdo *P = node->pdo;
	bool op = state == CO_NMT_OPERATIONAL;

	if (!P || op == P->operational)
		return;
	P->operational = op;
	for (uint16_t k = 0; k < P->n_rx + P->n_tx; k++)
		pdo_runtime_reset(P, &P->v[k], now_us);
}

const co_service co_svc_pdo = {
	.name = "pdo",
	.init = pdo_init,
	.fini = pdo_fini,
	.tick = pdo_tick,
	.reset_comm = pdo_reset_comm,
	.nmt_changed = pdo_nmt_changed,
};

/* ---- API ------------------------------------------------------------------------ */

static struct pdo *pdo_get(const co_node *node, co_pdo_dir dir, uint16_t nr)
{
	const struct co_pdo *P = node->pdo;

	if (!P || nr < 1 || nr > CO_PDO_MAX || P->slot[dir][nr - 1] == HEAP_NONE)
		return NULL;
	return &P->v[P->slot[dir][nr - 1]];
}

int co_pdo_tpdo_event(co_node *node, uint16_t nr, uint64_t now_us)
{
	struct co_pdo *P = node->pdo;
	struct pdo *p;

	if (nr < 1 || nr > CO_PDO_MAX)
		return -EINVAL;
	p = pdo_get(node, CO_PDO_TX, nr);
	if (!p)
		return -ENOENT;
	if (p->tt != CO_PDO_TT_SYNC_ACYCLIC && !tt_is_event(p->tt))
		return -EPERM;
	if (!P->operational || !p->valid)
		return -EAGAIN;
	node->now_us = now_us;
	if (p->tt == CO_PDO_TT_SYNC_ACYCLIC)
		p->pending = true;
	else
		tpdo_trigger(P, p, now_us);
	return 0;
}

int co_pdo_object_changed(co_node *node, uint16_t index, uint8_t sub, uint64_t now_us)
{
	struct co_pdo *P = node->pdo;
	uint32_t key = (uint32_t)index << 8 | sub;
	uint32_t lo, hi;
	uint16_t last = HEAP_NONE;
	int count = 0;

	if (!P || !P->operational)
		return 0;
	node->now_us = now_us;
	if (P->rev_dirty)
		pdo_map_rev_rebuild(P);
	lo = 0;
	hi = P->rev_n;
	while (lo < hi) {
		uint32_t mid = lo + (hi - lo) / 2;
		if (P->rev[mid].key < key)
			lo = mid + 1;
		else
			hi = mid;
	}
	for (; lo < P->rev_n && P->rev[lo].key == key; lo++) {
		struct pdo *p = &P->v[P->rev[lo].pdo];
		if (P->rev[lo].pdo == last)
			continue; /* object mapped twice in one PDO */
		last = P->rev[lo].pdo;
		if (!p->valid)
			continue;
		if (p->tt == CO_PDO_TT_SYNC_ACYCLIC) {
			p->pending = true;
			count++;
		} else if (tt_is_event(p->tt)) {
			tpdo_trigger(P, p, now_us);
			count++;
		}
	}
	return count;
}

void co_pdo_set_tx_gate(co_node *node, co_pdo_tx_gate_fn fn, void *ctx)
{
	struct co_pdo *P = node->pdo;

	if (!P)
		return;
	P->gate = fn;
	P->gate_ctx = fn ? ctx : NULL;
}

int co_pdo_tpdo_sent_by_peer(co_node *node, uint16_t nr, uint64_t at_us)
{
	struct co_pdo *P = node->pdo;
	struct pdo *p = pdo_get(node, CO_PDO_TX, nr);
	uint64_t until;

	if (!p)
		return -ENOENT;
	if (!P->operational || !p->valid)
		return -EAGAIN;
	P->stats.tx_by_peer++;
	until = at_us + (uint64_t)p->inhibit_100us * 100u;
	if (until > p->inhibit_until)
		p->inhibit_until = until;
	if (tt_is_event(p->tt) && p->event_ms)
		p->timer_us = at_us + (uint64_t)p->event_ms * 1000u;
	heap_update(P, p);
	return 0;
}

int co_pdo_tpdo_state_get(const co_node *node, uint16_t nr, co_pdo_tpdo_state *out)
{
	const struct pdo *p = pdo_get(node, CO_PDO_TX, nr);

	if (!p)
		return -ENOENT;
	*out = (co_pdo_tpdo_state){ .valid = p->valid,
				    .operational = node->pdo->operational,
				    .event_pending = p->event_pending,
				    .tt = p->tt,
				    .len = p->len,
				    .inhibit_100us = p->inhibit_100us,
				    .event_ms = p->event_ms,
				    .cob_id = p->cob,
				    .inhibit_until = p->inhibit_until };
	return 0;
}

int co_pdo_rpdo_request(co_node *node, uint16_t nr, uint64_t now_us)
{
	struct co_pdo *P = node->pdo;
	struct pdo *p = pdo_get(node, CO_PDO_RX, nr);
	co_frame f;
	uint32_t id;
	uint8_t flags;

	(void)now_us;
	if (!p)
		return -ENOENT;
	if (!P->operational || !p->valid)
		return -EAGAIN;
	co_cob_split(p->cob, &id, &flags);
	co_frame_init(&f, id, p->len);
	f.flags = flags | CO_FRAME_RTR;
	return co_node_send(node, &f);
}

uint16_t co_pdo_count(const co_node *node, co_pdo_dir dir)
{
	const struct co_pdo *P = node->pdo;

	if (!P)
		return 0;
	return dir == CO_PDO_TX ? P->n_tx : P->n_rx;
}

bool co_pdo_is_valid(const co_node *node, co_pdo_dir dir, uint16_t nr)
{
	const struct pdo *p = pdo_get(node, dir, nr);

	return p && p->valid;
}

int co_pdo_length(const co_node *node, co_pdo_dir dir, uint16_t nr)
{
	const struct pdo *p = pdo_get(node, dir, nr);

	return p ? p->len : -ENOENT;
}

int co_pdo_rpdo_state_get(const co_node *node, uint16_t nr, co_pdo_rpdo_state *out)
{
	const struct pdo *p = pdo_get(node, CO_PDO_RX, nr);

	if (!p)
		return -ENOENT;
	*out = (co_pdo_rpdo_state){ .valid = p->valid,
				    .faults = p->faults,
				    .mapped_len = p->len,
				    .event_ms = p->event_ms,
				    .cob_id = p->cob };
	return 0;
}

const co_pdo_stats *co_pdo_get_stats(const co_node *node)
{
	static const co_pdo_stats none;

	return node->pdo ? &node->pdo->stats : &none;
}
