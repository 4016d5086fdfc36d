/* SPDX-License-Identifier: MIT */
/*
 * NMT slave state machine and NMT master command sender (CiA 301 §7.3.2,
 * figure 48 "NMT state diagram"; §7.2.8.3.1 NMT services).
 *
 * The slave is a core/fsm.h machine, one handler per state. Its inputs:
 * an NMT command (the 2-byte frame of 000h; a local command or our own
 * broadcast goes through the same handlers as that frame), the boot-up
 * at the first tick after a reset (on_timeout of INITIALISING), and two
 * forced changes that are no command: 1029h error behaviour and a reset
 * communication the application starts itself.
 *
 * Resets are two steps on purpose: the command puts the node into
 * INITIALISING, whose on_enter runs co_node_reset_app/comm (every service
 * re-reads its objects), and only then the boot-up goes out and the node
 * enters PRE-OPERATIONAL. If the application calls co_node_reset_comm()
 * itself, our reset_comm op enters INITIALISING with the boot-up pending
 * and asks for an immediate tick, so the boot-up still follows the reset
 * of *all* services, never precedes it.
 */
#include <errno.h>
#include <stdlib.h>

#include "core/co_internal.h"
#include "core/fsm.h"
#include "core/nmt.h"

struct nmt_cmd {
	uint8_t target;
	uint8_t cs;
	uint8_t flags;
};

struct co_nmt {
	co_node *node;
	co_fsm fsm;        /* state: enum nmt_fsm_state */
	uint8_t leaving;   /* state byte being left (on_leave), for the event */
	uint8_t cmd_cs;    /* command being applied, 0 for a forced change */
	int cmd_rc;        /* its outcome: 0, or -EPERM when vetoed */
	bool boot_pending; /* INITIALISING: boot-up at the next tick */

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

/* The machine's states, in the order of the table below. */
enum nmt_fsm_state {
	NMT_ST_INITIALISING,
	NMT_ST_PRE_OPERATIONAL,
	NMT_ST_OPERATIONAL,
	NMT_ST_STOPPED,
	NMT_ST_COUNT
};

/* The heartbeat / guarding byte of each state (CiA 301 §7.2.8.3.2). */
static const uint8_t nmt_state_byte[NMT_ST_COUNT] = {
	[NMT_ST_INITIALISING] = CO_NMT_INITIALISING,
	[NMT_ST_PRE_OPERATIONAL] = CO_NMT_PRE_OPERATIONAL,
	[NMT_ST_OPERATIONAL] = CO_NMT_OPERATIONAL,
	[NMT_ST_STOPPED] = CO_NMT_STOPPED,
};

static const co_fsm_def nmt_fsm_def;

static int state_of_byte(uint8_t state)
{
	for (int i = 0; i < NMT_ST_COUNT; i++)
		if (nmt_state_byte[i] == state)
			return i;
	return -1;
}

const char *co_nmt_state_to_string(uint8_t state)
{
	return co_fsm_state_name(&nmt_fsm_def, state_of_byte(state));
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
	return node->nmt ? nmt_state_byte[co_fsm_state_of(&node->nmt->fsm)] : CO_NMT_OPERATIONAL;
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

static uint8_t state_byte(const struct co_nmt *nmt)
{
	return nmt_state_byte[co_fsm_state_of(&nmt->fsm)];
}

static void nmt_leave(void *obj, uint64_t now_us)
{
	struct co_nmt *nmt = obj;

	(void)now_us;
	nmt->leaving = state_byte(nmt);
}

/* Every state's entry: CO_EV_NMT_STATE and every service's nmt_changed,
 * unless the state was entered again (a reset while INITIALISING). */
static void announce(struct co_nmt *nmt, uint64_t now_us)
{
	co_node *node = nmt->node;
	co_event ev = { .kind = CO_EV_NMT_STATE };
	uint8_t state = state_byte(nmt);

	if (nmt->leaving == state)
		return;
	node->now_us = now_us;
	ev.u.nmt.state = state;
	ev.u.nmt.prev = nmt->leaving;
	ev.u.nmt.cs = nmt->cmd_cs;
	co_node_emit(node, &ev);
	co_node_nmt_changed(node, state, now_us);
}

static int announce_and_stay(void *obj, uint64_t now_us)
{
	announce(obj, now_us);
	return CO_FSM_STAY;
}

/* Boot-up message (CiA 301 §7.2.8.3.2.3): 700h + id, one byte 00h; then
 * PRE-OPERATIONAL. */
static int boot(struct co_nmt *nmt)
{
	co_node *node = nmt->node;
	co_frame f;

	nmt->boot_pending = false;
	if (node->node_id < 1 || node->node_id > 127)
		return CO_FSM_STAY; /* LSS unconfigured: stay INITIALISING (CiA 305) */
	co_frame_init(&f, CO_NMT_ERRCTRL_BASE + node->node_id, 1);
	f.data[0] = CO_NMT_INITIALISING;
	(void)co_node_send(node, &f);
	nmt->cmd_cs = 0; /* PRE-OPERATIONAL is no command's doing */
	return NMT_ST_PRE_OPERATIONAL;
}

/* INITIALISING entered: by a reset command, which resets the services
 * and boots at once; or by a forced reset communication, which boots at
 * the next tick. */
static int initialising_enter(void *obj, uint64_t now_us)
{
	struct co_nmt *nmt = obj;
	uint8_t cs = nmt->cmd_cs;

	announce(nmt, now_us);
	if (cs == CO_NMT_CS_RESET_NODE)
		co_node_reset_app(nmt->node, now_us);
	else if (cs == CO_NMT_CS_RESET_COMM)
		co_node_reset_comm(nmt->node, now_us);
	else
		return CO_FSM_STAY;
	return boot(nmt);
}

static int initialising_timeout(void *obj, uint64_t now_us)
{
	struct co_nmt *nmt = obj;

	(void)now_us;
	return nmt->boot_pending ? boot(nmt) : CO_FSM_STAY;
}

static bool is_reset(uint8_t cs)
{
	return cs == CO_NMT_CS_RESET_NODE || cs == CO_NMT_CS_RESET_COMM;
}

/* START, unless the application vetoes it (co_nmt_set_veto). */
static int start(struct co_nmt *nmt)
{
	if (nmt->veto &&
	    !nmt->veto(nmt->veto_ctx, nmt->node, state_byte(nmt), CO_NMT_OPERATIONAL)) {
		nmt->stats.vetoed++;
		nmt->cmd_rc = -EPERM;
		return CO_FSM_STAY;
	}
	return NMT_ST_OPERATIONAL;
}

/* Which command does what in which state (CiA 301 figure 48); a command
 * a state does not name leaves it as it is. In INITIALISING the node
 * waits for its boot-up; only resets apply. */
static int initialising_cmd(void *obj, const co_frame *f, uint64_t now_us)
{
	(void)obj;
	(void)now_us;
	return is_reset(f->data[0]) ? NMT_ST_INITIALISING : CO_FSM_STAY;
}

static int pre_operational_cmd(void *obj, const co_frame *f, uint64_t now_us)
{
	(void)now_us;
	switch (f->data[0]) {
	case CO_NMT_CS_START:
		return start(obj);
	case CO_NMT_CS_STOP:
		return NMT_ST_STOPPED;
	}
	return is_reset(f->data[0]) ? NMT_ST_INITIALISING : CO_FSM_STAY;
}

static int operational_cmd(void *obj, const co_frame *f, uint64_t now_us)
{
	(void)obj;
	(void)now_us;
	switch (f->data[0]) {
	case CO_NMT_CS_STOP:
		return NMT_ST_STOPPED;
	case CO_NMT_CS_ENTER_PREOP:
		return NMT_ST_PRE_OPERATIONAL;
	}
	return is_reset(f->data[0]) ? NMT_ST_INITIALISING : CO_FSM_STAY;
}

static int stopped_cmd(void *obj, const co_frame *f, uint64_t now_us)
{
	(void)now_us;
	switch (f->data[0]) {
	case CO_NMT_CS_START:
		return start(obj);
	case CO_NMT_CS_ENTER_PREOP:
		return NMT_ST_PRE_OPERATIONAL;
	}
	return is_reset(f->data[0]) ? NMT_ST_INITIALISING : CO_FSM_STAY;
}

static const co_fsm_state nmt_states[NMT_ST_COUNT] = {
	[NMT_ST_INITIALISING] = { .name = "initialising",
				  .on_enter = initialising_enter,
				  .on_frame = initialising_cmd,
				  .on_timeout = initialising_timeout,
				  .on_leave = nmt_leave },
	[NMT_ST_PRE_OPERATIONAL] = { .name = "pre-operational",
				     .on_enter = announce_and_stay,
				     .on_frame = pre_operational_cmd,
				     .on_leave = nmt_leave },
	[NMT_ST_OPERATIONAL] = { .name = "operational",
				 .on_enter = announce_and_stay,
				 .on_frame = operational_cmd,
				 .on_leave = nmt_leave },
	[NMT_ST_STOPPED] = { .name = "stopped",
			     .on_enter = announce_and_stay,
			     .on_frame = stopped_cmd,
			     .on_leave = nmt_leave },
};

static const co_fsm_def nmt_fsm_def = {
	.name = "nmt",
	.states = nmt_states,
	.n_states = NMT_ST_COUNT,
};

/* A state change that is no NMT command (1029h, an application's reset
 * communication). */
static void force(struct co_nmt *nmt, int state, uint64_t now_us)
{
	nmt->cmd_cs = 0;
	co_fsm_goto(&nmt->fsm, state, now_us);
}

/* Apply command cs (valid) as the frame 000h would: 0 or -EPERM. */
static int apply(co_node *node, uint8_t cs, uint64_t now_us)
{
	struct co_nmt *nmt = node->nmt;
	co_frame f;

	co_frame_init(&f, CO_NMT_COB_ID, 2);
	f.data[0] = cs;
	f.data[1] = node->node_id;
	nmt->cmd_cs = cs;
	nmt->cmd_rc = 0;
	co_fsm_frame(&nmt->fsm, &f, now_us);
	return nmt->cmd_rc;
}

int co_nmt_local_cmd(co_node *node, uint8_t cs, uint64_t now_us)
{
	if (!node->nmt)
		return -ENODEV;
	if (!co_nmt_cs_is_valid(cs))
		return -EINVAL;
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
		if (co_fsm_state_of(&node->nmt->fsm) == NMT_ST_OPERATIONAL)
			force(node->nmt, NMT_ST_PRE_OPERATIONAL, now_us);
		break;
	case CO_NMT_ERR_STOPPED:
		if (co_fsm_state_of(&node->nmt->fsm) == NMT_ST_PRE_OPERATIONAL ||
		    co_fsm_state_of(&node->nmt->fsm) == NMT_ST_OPERATIONAL)
			force(node->nmt, NMT_ST_STOPPED, now_us);
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
	nmt->node = node;
	co_fsm_init(&nmt->fsm, &nmt_fsm_def, nmt, NMT_ST_INITIALISING);
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

	co_fsm_timeout(&nmt->fsm, now_us); /* the boot-up, if one is pending */
	master_flush(node, now_us);
	return master_next_us(node);
}

static void nmt_reset_comm(co_node *node, uint64_t now_us)
{
	struct co_nmt *nmt = node->nmt;

	/* Reached through an NMT command (INITIALISING's on_enter boots right
	 * after) or through the application calling co_node_reset_comm():
	 * then the boot-up goes out at the next tick, after every service
	 * reset. */
	if (co_fsm_state_of(&nmt->fsm) != NMT_ST_INITIALISING)
		force(nmt, NMT_ST_INITIALISING, now_us);
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
