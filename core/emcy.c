/* SPDX-License-Identifier: MIT */
/*
 * EMCY producer and consumer (CiA 301 §7.2.7, §7.5.2.2/4/8/9/22).
 *
 * Why a queue instead of dropping: 1015h only promises that two EMCYs are
 * at least the inhibit time apart. A device that hits two faults within a
 * millisecond (e.g. an RPDO length error, then a heartbeat loss) must
 * still report both, so the second frame waits; the queue is bounded so a
 * fault storm cannot grow memory, and an overflow is an error to the
 * caller, not a silent loss.
 *
 * Why the active error list: 1001h is the OR of the errors that are
 * present now, not of the ones that ever happened (that is 1003h). The
 * list lets co_emcy_clear() recompute the register and know when the last
 * error went away, which is when CiA 301 wants the "error reset" EMCY.
 */
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/co_internal.h"
#include "core/emcy.h"
#include "core/nmt.h"
#include "core/sdo.h"

#define EMCY_LEN 8u
#define EMCY_HIST_MAX 254u
#define EMCY_CONS_MAX 127u

#define COB_INVALID 0x80000000u
#define COB_RESERVED 0x40000000u
#define COB_EXT CO_COB_EXT

struct emcy_active {
	uint16_t code;
	uint8_t bits;
};

struct co_emcy {
	co_node *node;
	uint8_t reg;      /* internal copy of 1001h */
	uint8_t hist_len; /* subs 1..hist_len of 1003h exist */
	struct emcy_active active[CO_EMCY_ACTIVE_MAX];
	uint8_t n_active;

	co_frame queue[CO_EMCY_QUEUE_LEN];
	uint8_t q_head, q_count;
	uint64_t last_tx_us;
	bool tx_once; /* last_tx_us is meaningful */

	int cons_rx[EMCY_CONS_MAX + 1]; /* receiver per 1028h sub, -1 none */
	co_emcy_stats stats;
};

/* ---- helpers ------------------------------------------------------------ */

const char *co_emcy_code_to_string(uint16_t code)
{
	switch (code) {
	case CO_EMCY_NO_ERROR:
		return "error reset or no error";
	case CO_EMCY_GENERIC:
		return "generic error";
	case CO_EMCY_CAN_OVERRUN:
		return "CAN overrun";
	case CO_EMCY_CAN_PASSIVE:
		return "CAN in error passive mode";
	case CO_EMCY_LIFE_GUARD:
		return "life guard or heartbeat error";
	case CO_EMCY_BUS_OFF_RECOVERED:
		return "recovered from bus off";
	case CO_EMCY_CAN_ID_COLLISION:
		return "CAN-ID collision";
	case CO_EMCY_PDO_LENGTH:
		return "PDO not processed due to length error";
	case CO_EMCY_PDO_LENGTH_HIGH:
		return "PDO length exceeded";
	case CO_EMCY_DAM_MPDO:
		return "DAM MPDO not processed";
	case CO_EMCY_SYNC_LENGTH:
		return "unexpected SYNC data length";
	case CO_EMCY_RPDO_TIMEOUT:
		return "RPDO timeout";
	}
	return "?";
}

static co_od_entry *find(const co_node *node, uint16_t idx, uint8_t sub)
{
	return co_od_find(node->od, idx, sub);
}

static void reg_publish(struct co_emcy *em)
{
	co_od_entry *e = find(em->node, 0x1001, 0);

	if (e)
		co_od_entry_set_raw(e, em->reg);
}

static void reg_recompute(struct co_emcy *em)
{
	uint8_t r = 0;

	for (unsigned i = 0; i < em->n_active; i++)
		r |= em->active[i].bits;
	em->reg = r;
	reg_publish(em);
}

/* COB-ID the producer uses now; false if production is disabled. */
static bool producer_cob(const struct co_emcy *em, uint32_t *id, uint8_t *flags)
{
	co_od_entry *e = find(em->node, 0x1014, 0);
	uint32_t v;

	if (!e) {
		if (em->node->node_id < 1 || em->node->node_id > 127)
			return false;
		*id = CO_EMCY_COB_BASE + em->node->node_id;
		*flags = 0;
		return true;
	}
	v = (uint32_t)co_od_entry_raw(e);
	if (v & COB_INVALID)
		return false;
	co_cob_split(v, id, flags);
	return true;
}

static uint64_t inhibit_us(const struct co_emcy *em)
{
	uint16_t v = 0;

	(void)co_od_get_u16(em->node->od, 0x1015, 0, &v);
	return (uint64_t)v * 100u;
}

/* ---- 1003h: history, newest first --------------------------------------- */

static void history_push(struct co_emcy *em, uint16_t code, const uint8_t *msef)
{
	co_od_entry *e0 = find(em->node, 0x1003, 0);
	uint8_t n;

	if (!e0 || !em->hist_len)
		return;
	n = (uint8_t)co_od_entry_raw(e0);
	if (n > em->hist_len)
		n = em->hist_len;
	/* Shift down: sub k+1 <- sub k; the oldest falls off the end. */
	for (unsigned s = (n < em->hist_len ? n + 1u : em->hist_len); s > 1; s--)
		co_od_entry_set_raw(find(em->node, 0x1003, (uint8_t)s),
				    co_od_entry_raw(find(em->node, 0x1003, (uint8_t)(s - 1))));
	/* Bits 31..16: manufacturer-specific additional information; we
	 * keep the first two manufacturer bytes of the EMCY there. */
	co_od_entry_set_raw(find(em->node, 0x1003, 1),
			    (uint32_t)code | ((uint32_t)co_get_le16(msef) << 16));
	if (n < em->hist_len)
		n++;
	co_od_entry_set_raw(e0, n);
}

static uint32_t hist0_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)ctx;
	(void)e;
	/* CiA 301 §7.5.2.4: only 0 may be written (delete the history). */
	if (!a->data || a->size != 1 || a->data[0] != 0)
		return SDO_AB_VALUE;
	return 0;
}

static void hist0_after(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct co_emcy *em = ctx;

	(void)e;
	(void)a;
	for (unsigned s = 1; s <= em->hist_len; s++)
		co_od_entry_set_raw(find(em->node, 0x1003, (uint8_t)s), 0);
}

static uint32_t hist_read(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct co_emcy *em = ctx;
	uint8_t n = 0;

	(void)a;
	(void)co_od_get_u8(em->node->od, 0x1003, 0, &n);
	return e->sub > n ? SDO_AB_NO_DATA : 0;
}

static const co_od_hooks hist0_hooks = {
	.check_write = hist0_check,
	.after_write = hist0_after,
};
static const co_od_hooks hist_hooks = { .read = hist_read };

/* ---- 1014h ------------------------------------------------------------- */

static uint32_t cob_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	uint32_t cur = (uint32_t)co_od_entry_raw(e), v, id;

	(void)ctx;
	if (!a->data || a->size != 4)
		return SDO_AB_TYPE_LEN;
	v = co_get_le32(a->data);
	if (v & COB_RESERVED)
		return SDO_AB_VALUE;
	if (v & COB_INVALID)
		return 0;
	id = v & ((v & COB_EXT) ? CO_FRAME_EFF_MASK : CO_FRAME_SFF_MASK);
	if (v & ~(COB_INVALID | COB_EXT | ((v & COB_EXT) ? CO_FRAME_EFF_MASK : CO_FRAME_SFF_MASK)))
		return SDO_AB_VALUE;
	if (!(v & COB_EXT) && co_cob_is_restricted(id))
		return SDO_AB_VALUE;
	/* CiA 301 §7.5.2.7: a valid COB-ID is changed only through invalid. */
	if (!(cur & COB_INVALID) && (cur & ~COB_INVALID) != (v & ~COB_INVALID))
		return SDO_AB_VALUE;
	return 0;
}

static const co_od_hooks cob_hooks = { .check_write = cob_check };

/* ---- transmission ------------------------------------------------------ */

static void tx_now(struct co_emcy *em, const co_frame *f, uint64_t now_us)
{
	uint8_t st = co_nmt_get_state(em->node);

	/* CiA 301 table 88: no EMCY in STOPPED (nor before the boot-up). A
	 * suppressed frame does not start an inhibit time. */
	if (st == CO_NMT_STOPPED || st == CO_NMT_INITIALISING) {
		em->stats.tx_suppressed++;
		return;
	}
	em->last_tx_us = now_us;
	em->tx_once = true;
	if (co_node_send(em->node, f) == 0)
		em->stats.tx++;
}

static uint64_t queue_next_us(const struct co_emcy *em)
{
	if (!em->q_count)
		return CO_NO_DEADLINE;
	return em->last_tx_us + inhibit_us(em);
}

static void queue_flush(struct co_emcy *em, uint64_t now_us)
{
	/* One frame per inhibit period; with 1015h = 0 all go at once. */
	while (em->q_count && now_us >= em->last_tx_us + inhibit_us(em)) {
		co_frame f = em->queue[em->q_head];
		em->q_head = (uint8_t)((em->q_head + 1) % CO_EMCY_QUEUE_LEN);
		em->q_count--;
		tx_now(em, &f, now_us);
		if (inhibit_us(em))
			break;
	}
}

static int produce(struct co_emcy *em, uint16_t code, uint8_t reg, const uint8_t *msef,
		   uint64_t now_us)
{
	co_frame f;
	uint32_t id;
	uint8_t flags;

	if (!producer_cob(em, &id, &flags)) {
		em->stats.tx_suppressed++;
		return 0;
	}
	co_frame_init(&f, id, EMCY_LEN);
	f.flags = flags;
	co_put_le16(&f.data[0], code);
	f.data[2] = reg;
	memcpy(&f.data[3], msef, 5);

	if (!em->q_count && (!em->tx_once || now_us >= em->last_tx_us + inhibit_us(em))) {
		tx_now(em, &f, now_us);
		return 0;
	}
	if (em->q_count >= CO_EMCY_QUEUE_LEN) {
		em->stats.overflow++;
		return -ENOBUFS;
	}
	em->queue[(em->q_head + em->q_count) % CO_EMCY_QUEUE_LEN] = f;
	em->q_count++;
	em->stats.queued++;
	co_node_deadline_lower(em->node, queue_next_us(em));
	return 0;
}

/* ---- public producer API ----------------------------------------------- */

int co_emcy_send(co_node *node, uint16_t code, uint8_t reg_bits, const uint8_t msef[5],
		 uint64_t now_us)
{
	static const uint8_t zero[5];
	struct co_emcy *em = node->emcy;
	int rc_active = 0, rc;
	unsigned i;

	if (!em)
		return -ENODEV;
	if (code == CO_EMCY_NO_ERROR)
		return -EINVAL;
	if (!msef)
		msef = zero;
	node->now_us = now_us;
	reg_bits |= CO_EMCY_REG_GENERIC;
	for (i = 0; i < em->n_active && em->active[i].code != code; i++)
		;
	if (i < em->n_active)
		em->active[i].bits = reg_bits;
	else if (em->n_active < CO_EMCY_ACTIVE_MAX)
		em->active[em->n_active++] = (struct emcy_active){ .code = code, .bits = reg_bits };
	else
		rc_active = -ENOSPC;
	reg_recompute(em);
	if (rc_active) { /* not tracked, but the register must show it */
		em->reg |= reg_bits;
		reg_publish(em);
	}
	history_push(em, code, msef);
	rc = produce(em, code, em->reg, msef, now_us);
	return rc ? rc : rc_active;
}

int co_emcy_clear(co_node *node, uint16_t code, uint64_t now_us)
{
	static const uint8_t zero[5];
	struct co_emcy *em = node->emcy;
	unsigned i;

	if (!em)
		return -ENODEV;
	for (i = 0; i < em->n_active && em->active[i].code != code; i++)
		;
	if (i == em->n_active)
		return -ENOENT;
	node->now_us = now_us;
	em->active[i] = em->active[--em->n_active];
	reg_recompute(em);
	if (em->n_active)
		return 0;
	return produce(em, CO_EMCY_NO_ERROR, 0, zero, now_us);
}

int co_emcy_clear_all(co_node *node, uint64_t now_us)
{
	static const uint8_t zero[5];
	struct co_emcy *em = node->emcy;

	if (!em)
		return -ENODEV;
	if (!em->n_active)
		return 0;
	node->now_us = now_us;
	em->n_active = 0;
	reg_recompute(em);
	return produce(em, CO_EMCY_NO_ERROR, 0, zero, now_us);
}

uint8_t co_emcy_error_register(const co_node *node)
{
	return node->emcy ? node->emcy->reg : 0;
}

int co_emcy_is_active(const co_node *node, uint16_t code)
{
	const struct co_emcy *em = node->emcy;

	if (!em)
		return 0;
	for (unsigned i = 0; i < em->n_active; i++)
		if (em->active[i].code == code)
			return 1;
	return 0;
}

const co_emcy_stats *co_emcy_get_stats(const co_node *node)
{
	return node->emcy ? &node->emcy->stats : NULL;
}

/* ---- consumer (1028h) -------------------------------------------------- */

static void cons_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	struct co_emcy *em = node->emcy;
	co_event ev = { .kind = CO_EV_EMCY_RX };

	(void)now_us;
	if (f->flags & CO_FRAME_RTR)
		return;
	if (f->len != EMCY_LEN) {
		em->stats.rx_invalid++;
		return;
	}
	em->stats.rx++;
	ev.u.emcy.node = (uint8_t)(uintptr_t)arg;
	ev.u.emcy.code = co_get_le16(&f->data[0]);
	ev.u.emcy.reg = f->data[2];
	memcpy(ev.u.emcy.msef, &f->data[3], 5);
	ev.u.emcy.cob_id = f->id | ((f->flags & CO_FRAME_EXT) ? COB_EXT : 0);
	co_node_emit(node, &ev);
}

/* (Re)attach the receiver of 1028h:sub to its current value. */
static int cons_apply(struct co_emcy *em, uint8_t sub)
{
	co_od_entry *e = find(em->node, 0x1028, sub);
	uint32_t v, id;
	uint8_t flags;
	int *h = &em->cons_rx[sub];

	if (!e || (v = (uint32_t)co_od_entry_raw(e)) & COB_INVALID) {
		if (*h >= 0)
			co_rx_disable(em->node, *h);
		return 0;
	}
	co_cob_split(v, &id, &flags);
	if (*h >= 0)
		return co_rx_move(em->node, *h, id, flags);
	*h = co_rx_register(em->node, id, flags, cons_rx, (void *)(uintptr_t)sub);
	return *h < 0 ? *h : 0;
}

static uint32_t cons_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	uint32_t v;

	(void)ctx;
	(void)e;
	if (!a->data || a->size != 4)
		return SDO_AB_TYPE_LEN;
	v = co_get_le32(a->data);
	if (v & COB_RESERVED)
		return SDO_AB_VALUE;
	if (!(v & COB_EXT) && (v & 0x1FFFF800u))
		return SDO_AB_VALUE;
	return 0;
}

static void cons_after(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)a;
	(void)cons_apply(ctx, e->sub);
}

static const co_od_hooks cons_hooks = {
	.check_write = cons_check,
	.after_write = cons_after,
};

/* ---- service ------------------------------------------------------------ */

static int emcy_init(co_node *node)
{
	struct co_emcy *em = calloc(1, sizeof(*em));
	co_od_entry *e;
	int rc;

	if (!em)
		return -ENOMEM;
	node->emcy = em;
	em->node = node;
	for (unsigned s = 0; s <= EMCY_CONS_MAX; s++)
		em->cons_rx[s] = -1;

	if ((e = find(node, 0x1003, 0)) != NULL) {
		co_od_entry_set_hooks(e, &hist0_hooks, em);
		while (em->hist_len < EMCY_HIST_MAX &&
		       (e = find(node, 0x1003, (uint8_t)(em->hist_len + 1)))) {
			co_od_entry_set_hooks(e, &hist_hooks, em);
			em->hist_len++;
		}
	}
	if ((e = find(node, 0x1014, 0)) != NULL)
		co_od_entry_set_hooks(e, &cob_hooks, em);
	for (unsigned s = 1; s <= EMCY_CONS_MAX; s++) {
		if (!(e = find(node, 0x1028, (uint8_t)s)))
			continue;
		co_od_entry_set_hooks(e, &cons_hooks, em);
		if ((rc = cons_apply(em, (uint8_t)s)) != 0)
			return rc;
	}
	reg_publish(em);
	return 0;
}

static void emcy_fini(co_node *node)
{
	free(node->emcy);
	node->emcy = NULL;
}

static uint64_t emcy_tick(co_node *node, uint64_t now_us)
{
	struct co_emcy *em = node->emcy;

	queue_flush(em, now_us);
	return queue_next_us(em);
}

static void emcy_reset_comm(co_node *node, uint64_t now_us)
{
	struct co_emcy *em = node->emcy;

	(void)now_us;
	/* Frames produced before the reset describe a communication setup
	 * that no longer exists; the errors themselves stay active (1001h is
	 * recomputed, the OD reset zeroed it). */
	em->q_count = 0;
	em->q_head = 0;
	em->tx_once = false;
	reg_publish(em);
	for (unsigned s = 1; s <= EMCY_CONS_MAX; s++)
		if (find(node, 0x1028, (uint8_t)s))
			(void)cons_apply(em, (uint8_t)s);
}

const co_service co_svc_emcy = {
	.name = "emcy",
	.init = emcy_init,
	.fini = emcy_fini,
	.tick = emcy_tick,
	.reset_comm = emcy_reset_comm,
};

/* ---- standard objects ---------------------------------------------------- */

int co_od_add_comm_defaults_emcy(co_od *od, uint8_t node_id, uint8_t history_len, uint8_t consumers,
				 int consume_all)
{
	int rc;

	if (!od || node_id < 1 || node_id > 127 || history_len > EMCY_HIST_MAX ||
	    consumers > EMCY_CONS_MAX)
		return -EINVAL;
	if ((rc = co_od_ensure_num(od, 0x1001, 0, CO_T_UNSIGNED8, CO_ACC_RO | CO_ACC_TPDO, 0, 0)))
		return rc;
	if (history_len) {
		if ((rc = co_od_ensure_num(od, 0x1003, 0, CO_T_UNSIGNED8, CO_ACC_RW, 0,
					   CO_OBJ_ARRAY)))
			return rc;
		for (unsigned s = 1; s <= history_len; s++)
			if ((rc = co_od_ensure_num(od, 0x1003, (uint8_t)s, CO_T_UNSIGNED32,
						   CO_ACC_RO, 0, CO_OBJ_ARRAY)))
				return rc;
	}
	if ((rc = co_od_ensure_num(od, 0x1014, 0, CO_T_UNSIGNED32, CO_ACC_RW,
				   CO_EMCY_COB_BASE + node_id, 0)))
		return rc;
	if ((rc = co_od_ensure_num(od, 0x1015, 0, CO_T_UNSIGNED16, CO_ACC_RW, 0, 0)))
		return rc;
	if (consumers) {
		if ((rc = co_od_ensure_num(od, 0x1028, 0, CO_T_UNSIGNED8, CO_ACC_RO, consumers,
					   CO_OBJ_ARRAY)))
			return rc;
		for (unsigned s = 1; s <= consumers; s++)
			if ((rc = co_od_ensure_num(
				     od, 0x1028, (uint8_t)s, CO_T_UNSIGNED32, CO_ACC_RW,
				     (CO_EMCY_COB_BASE + s) | (consume_all ? 0 : COB_INVALID),
				     CO_OBJ_ARRAY)))
				return rc;
	}
	return 0;
}
