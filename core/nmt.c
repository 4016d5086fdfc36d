/* SPDX-License-Identifier: MIT */
/*
 * NMT slave state machine and NMT master command sender (CiA 301 §7.3.2,
 * figure 48 "NMT state diagram"; §7.2.8.3.1 NMT services).
 *
 * The slave is a table of (state, command) -> handler. Resets are two
 * steps on purpose: the command puts the node into INITIALISING and runs
 * co_node_reset_app/comm (every service re-reads its objects), and only
 * then the boot-up goes out and the node enters PRE-OPERATIONAL. If the
 * application calls co_node_reset_comm() itself, our reset_comm op marks
 * the boot-up as pending and asks for an immediate tick, so the boot-up
 * still follows the reset of *all* services, never precedes it.
 */
#include <errno.h>
#include <stdlib.h>

#include "core/co_internal.h"
#include "core/nmt.h"

struct nmt_cmd {
	uint8_t target;
	uint8_t cs;
	uint8_t flags;
};

struct co_nmt {
	uint8_t state;
	bool boot_pending;

	co_nmt_veto_fn veto;
	void *veto_ctx;
	co_nmt_rx_filter_fn rx_filter;
	void *rx_filter_ctx;

	/* master */
	struct nmt_cmd q[CO_NMT_MASTER_QUEUE_LEN];
	uint8_t q_head, q_count;
	uint64_t last_tx_us;
	bool tx_once;

	co_nmt_stats stats;
};

const char *co_nmt_state_to_string(uint8_t state)
{
	switch (state) {
	case CO_NMT_INITIALISING:
		return "initialising";
	case CO_NMT_STOPPED:
		return "stopped";
	case CO_NMT_OPERATIONAL:
		return "operational";
	case CO_NMT_PRE_OPERATIONAL:
		return "pre-operational";
	}
	return "?";
}

const char *co_nmt_cs_to_string(uint8_t cs)
{
	switch (cs) {
	case CO_NMT_CS_START:
		return "start";
	case CO_NMT_CS_STOP:
		return "stop";
	case CO_NMT_CS_ENTER_PREOP:
		return "enter-pre-operational";
	case CO_NMT_CS_RESET_NODE:
		return "reset-node";
	case CO_NMT_CS_RESET_COMM:
		return "reset-comm";
	}
	return "?";
}

bool co_nmt_cs_is_valid(uint8_t cs)
{
	return cs == CO_NMT_CS_START || cs == CO_NMT_CS_STOP || cs == CO_NMT_CS_ENTER_PREOP ||
	       cs == CO_NMT_CS_RESET_NODE || cs == CO_NMT_CS_RESET_COMM;
}

uint8_t co_nmt_get_state(const co_node *node)
{
	/* Without the NMT service the node behaves as always operational
	 * (a bare test node): nothing is held back. */
	return node->nmt ? node->nmt->state : CO_NMT_OPERATIONAL;
}

const co_nmt_stats *co_nmt_get_stats(const co_node *node)
{
	return node->nmt ? &node->nmt->stats : NULL;
}

void co_nmt_set_veto(co_node *node, co_nmt_veto_fn fn, void *ctx)
{
	if (!node->nmt)
		return;
	node->nmt->veto = fn;
	node->nmt->veto_ctx = ctx;
}

/* ---- slave state machine ------------------------------------------------- */

void co_nmt_set_rx_filter(co_node *node, co_nmt_rx_filter_fn fn, void *ctx)
{
	if (!node->nmt)
		return;
	node->nmt->rx_filter = fn;
	node->nmt->rx_filter_ctx = ctx;
}

static void enter(co_node *node, uint8_t state, uint8_t cs, uint64_t now_us)
{
	struct co_nmt *nmt = node->nmt;
	uint8_t prev = nmt->state;
	co_event ev = { .kind = CO_EV_NMT_STATE };

	if (prev == state)
		return;
	nmt->state = state;
	node->now_us = now_us;
	ev.u.nmt.state = state;
	ev.u.nmt.prev = prev;
	ev.u.nmt.cs = cs;
	co_node_emit(node, &ev);
	co_node_nmt_changed(node, state, now_us);
}

/* Boot-up message (CiA 301 §7.2.8.3.2.3): 700h + id, one byte 00h. */
static void boot(co_node *node, uint64_t now_us)
{
	struct co_nmt *nmt = node->nmt;
	co_frame f;

	nmt->boot_pending = false;
	if (node->node_id < 1 || node->node_id > 127)
		return; /* LSS unconfigured: stay INITIALISING (CiA 305) */
	co_frame_init(&f, CO_NMT_ERRCTRL_BASE + node->node_id, 1);
	f.data[0] = CO_NMT_INITIALISING;
	(void)co_node_send(node, &f);
	enter(node, CO_NMT_PRE_OPERATIONAL, 0, now_us);
}

typedef int (*nmt_handler)(co_node *node, uint8_t cs, uint64_t now_us);

static int h_start(co_node *node, uint8_t cs, uint64_t now_us)
{
	struct co_nmt *nmt = node->nmt;

	if (nmt->state == CO_NMT_OPERATIONAL)
		return 0;
	if (nmt->veto && !nmt->veto(nmt->veto_ctx, node, nmt->state, CO_NMT_OPERATIONAL)) {
		nmt->stats.vetoed++;
		return -EPERM;
	}
	enter(node, CO_NMT_OPERATIONAL, cs, now_us);
	return 0;
}

static int h_stop(co_node *node, uint8_t cs, uint64_t now_us)
{
	enter(node, CO_NMT_STOPPED, cs, now_us);
	return 0;
}

static int h_preop(co_node *node, uint8_t cs, uint64_t now_us)
{
	enter(node, CO_NMT_PRE_OPERATIONAL, cs, now_us);
	return 0;
}

static int h_reset(co_node *node, uint8_t cs, uint64_t now_us)
{
	enter(node, CO_NMT_INITIALISING, cs, now_us);
	if (cs == CO_NMT_CS_RESET_NODE)
		co_node_reset_app(node, now_us);
	else
		co_node_reset_comm(node, now_us);
	boot(node, now_us);
	return 0;
}

static int h_ignore(co_node *node, uint8_t cs, uint64_t now_us)
{
	(void)node;
	(void)cs;
	(void)now_us;
	return 0;
}

/* Which command does what in which state (CiA 301 figure 48). In
 * INITIALISING the node waits for its boot-up; only resets apply. */
enum {
	ST_INIT,
	ST_PREOP,
	ST_OP,
	ST_STOPPED,
	ST_COUNT
};
enum {
	CMD_START,
	CMD_STOP,
	CMD_PREOP,
	CMD_RESET_NODE,
	CMD_RESET_COMM,
	CMD_COUNT
};

static const nmt_handler nmt_table[ST_COUNT][CMD_COUNT] = {
	[ST_INIT] = { h_ignore, h_ignore, h_ignore, h_reset, h_reset },
	[ST_PREOP] = { h_start, h_stop, h_ignore, h_reset, h_reset },
	[ST_OP] = { h_ignore, h_stop, h_preop, h_reset, h_reset },
	[ST_STOPPED] = { h_start, h_ignore, h_preop, h_reset, h_reset },
};

static int state_row(uint8_t state)
{
	switch (state) {
	case CO_NMT_PRE_OPERATIONAL:
		return ST_PREOP;
	case CO_NMT_OPERATIONAL:
		return ST_OP;
	case CO_NMT_STOPPED:
		return ST_STOPPED;
	default:
		return ST_INIT;
	}
}

static int cmd_col(uint8_t cs)
{
	switch (cs) {
	case CO_NMT_CS_START:
		return CMD_START;
	case CO_NMT_CS_STOP:
		return CMD_STOP;
	case CO_NMT_CS_ENTER_PREOP:
		return CMD_PREOP;
	case CO_NMT_CS_RESET_NODE:
		return CMD_RESET_NODE;
	case CO_NMT_CS_RESET_COMM:
		return CMD_RESET_COMM;
	default:
		return -1;
	}
}

static int apply(co_node *node, uint8_t cs, uint64_t now_us)
{
	int col = cmd_col(cs);

	if (col < 0)
		return -EINVAL;
	return nmt_table[state_row(node->nmt->state)][col](node, cs, now_us);
}

int co_nmt_local_cmd(co_node *node, uint8_t cs, uint64_t now_us)
{
	if (!node->nmt)
		return -ENODEV;
	node->now_us = now_us;
	return apply(node, cs, now_us);
}

static void nmt_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	struct co_nmt *nmt = node->nmt;
	uint8_t target;

	(void)arg;
	if ((f->flags & CO_FRAME_RTR) || f->len != 2 || !co_nmt_cs_is_valid(f->data[0])) {
		nmt->stats.cmd_invalid++;
		return;
	}
	target = f->data[1];
	if (target != 0 && target != node->node_id)
		return;
	nmt->stats.cmd_rx++;
	if (nmt->rx_filter &&
	    !nmt->rx_filter(nmt->rx_filter_ctx, node, f->data[0], target, now_us)) {
		nmt->stats.cmd_filtered++;
		return;
	}
	(void)apply(node, f->data[0], now_us);
}

/* ---- 1029h error behaviour ---------------------------------------------- */

int co_nmt_error_behaviour(co_node *node, uint8_t sub, uint64_t now_us)
{
	uint8_t b = CO_NMT_ERR_PREOP; /* CiA 301 §7.5.2.32: default */

	if (!node->nmt)
		return -ENODEV;
	(void)co_od_get_u8(node->od, 0x1029, sub, &b);
	node->now_us = now_us;
	switch (b) {
	case CO_NMT_ERR_PREOP:
		if (node->nmt->state == CO_NMT_OPERATIONAL)
			enter(node, CO_NMT_PRE_OPERATIONAL, 0, now_us);
		break;
	case CO_NMT_ERR_STOPPED:
		if (node->nmt->state != CO_NMT_INITIALISING)
			enter(node, CO_NMT_STOPPED, 0, now_us);
		break;
	default: /* 1 = no change; 3.. reserved: no change either */
		b = CO_NMT_ERR_NO_CHANGE;
		break;
	}
	return b;
}

int co_nmt_comm_error(co_node *node, uint64_t now_us)
{
	return co_nmt_error_behaviour(node, 1, now_us);
}

/* ---- master ---------------------------------------------------------------- */

static uint64_t inhibit_us(const co_node *node)
{
	uint16_t v = 0;

	(void)co_od_get_u16(node->od, 0x102A, 0, &v);
	return (uint64_t)v * 100u;
}

static void master_tx(co_node *node, const struct nmt_cmd *c, uint64_t now_us)
{
	struct co_nmt *nmt = node->nmt;
	co_frame f;

	co_frame_init(&f, CO_NMT_COB_ID, 2);
	f.data[0] = c->cs;
	f.data[1] = c->target;
	nmt->last_tx_us = now_us;
	nmt->tx_once = true;
	if (co_node_send(node, &f) == 0)
		nmt->stats.master_tx++;
	/* Applied after the frame so the bus sees the command before our own
	 * boot-up (reset) or state heartbeat. */
	if (c->target == 0 && (c->flags & CO_NMT_SEND_SELF))
		(void)apply(node, c->cs, now_us);
}

static uint64_t master_next_us(const co_node *node)
{
	const struct co_nmt *nmt = node->nmt;

	return nmt->q_count ? nmt->last_tx_us + inhibit_us(node) : CO_NO_DEADLINE;
}

static void master_flush(co_node *node, uint64_t now_us)
{
	struct co_nmt *nmt = node->nmt;

	while (nmt->q_count && now_us >= nmt->last_tx_us + inhibit_us(node)) {
		struct nmt_cmd c = nmt->q[nmt->q_head];
		nmt->q_head = (uint8_t)((nmt->q_head + 1) % CO_NMT_MASTER_QUEUE_LEN);
		nmt->q_count--;
		master_tx(node, &c, now_us);
		if (inhibit_us(node))
			break;
	}
}

int co_nmt_master_send_ex(co_node *node, uint8_t target, uint8_t cs, unsigned flags,
			  uint64_t now_us)
{
	struct co_nmt *nmt = node->nmt;
	struct nmt_cmd c = { .target = target, .cs = cs, .flags = (uint8_t)flags };

	if (!nmt)
		return -ENODEV;
	if (target > 127 || !co_nmt_cs_is_valid(cs) || (flags & ~CO_NMT_SEND_SELF))
		return -EINVAL;
	node->now_us = now_us;
	if (!nmt->q_count && (!nmt->tx_once || now_us >= nmt->last_tx_us + inhibit_us(node))) {
		master_tx(node, &c, now_us);
		return 0;
	}
	if (nmt->q_count >= CO_NMT_MASTER_QUEUE_LEN) {
		nmt->stats.master_overflow++;
		return -ENOBUFS;
	}
	nmt->q[(nmt->q_head + nmt->q_count) % CO_NMT_MASTER_QUEUE_LEN] = c;
	nmt->q_count++;
	nmt->stats.master_queued++;
	co_node_deadline_lower(node, master_next_us(node));
	return 0;
}

int co_nmt_master_send(co_node *node, uint8_t target, uint8_t cs, uint64_t now_us)
{
	return co_nmt_master_send_ex(node, target, cs, 0, now_us);
}

unsigned co_nmt_master_pending(const co_node *node)
{
	return node->nmt ? node->nmt->q_count : 0;
}

/* ---- service ------------------------------------------------------------- */

static int nmt_init(co_node *node)
{
	struct co_nmt *nmt = calloc(1, sizeof(*nmt));
	int h;

	if (!nmt)
		return -ENOMEM;
	node->nmt = nmt;
	nmt->state = CO_NMT_INITIALISING;
	h = co_rx_register(node, CO_NMT_COB_ID, 0, nmt_rx, NULL);
	if (h < 0)
		return h;
	/* Boot at the first tick: the caller's clock is not known here and
	 * the other services are not initialised yet. */
	nmt->boot_pending = true;
	co_node_deadline_lower(node, 0);
	return 0;
}

static void nmt_fini(co_node *node)
{
	free(node->nmt);
	node->nmt = NULL;
}

static uint64_t nmt_tick(co_node *node, uint64_t now_us)
{
	struct co_nmt *nmt = node->nmt;

	if (nmt->boot_pending && nmt->state == CO_NMT_INITIALISING)
		boot(node, now_us);
	master_flush(node, now_us);
	return master_next_us(node);
}

static void nmt_reset_comm(co_node *node, uint64_t now_us)
{
	struct co_nmt *nmt = node->nmt;

	/* Reached through an NMT command (h_reset boots right after) or
	 * through the application calling co_node_reset_comm(): then the
	 * boot-up goes out at the next tick, after every service reset. */
	enter(node, CO_NMT_INITIALISING, 0, now_us);
	nmt->boot_pending = true;
	co_node_deadline_lower(node, now_us);
}

const co_service co_svc_nmt = {
	.name = "nmt",
	.init = nmt_init,
	.fini = nmt_fini,
	.tick = nmt_tick,
	.reset_comm = nmt_reset_comm,
};

/* ---- standard objects ---------------------------------------------------- */

int co_od_add_comm_defaults_nmt(co_od *od, uint8_t n_subs)
{
	int rc;

	if (!od || n_subs < 1 || n_subs > 254)
		return -EINVAL;
	if (!co_od_has_index(od, 0x1029)) {
		if ((rc = co_od_add_array(od, 0x1029, CO_T_UNSIGNED8, n_subs, CO_ACC_RW,
					  CO_NMT_ERR_PREOP)))
			return rc;
	}
	return co_od_ensure_num(od, 0x102A, 0, CO_T_UNSIGNED16, CO_ACC_RW, 0, 0);
}
