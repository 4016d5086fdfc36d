/* SPDX-License-Identifier: MIT */
/*
 * Communication faults of the node itself (core/commfault.h).
 *
 * Why episodes: a sick segment produces error frames, lost frames and
 * state changes by the thousand. One EMCY per occurrence would load the
 * very bus that is in trouble and bury the one message a service engineer
 * needs; one EMCY per episode, and its reset when the episode ends, tells
 * "it began" and "it is over" (CiA 301 §7.2.7: the error reset once no
 * error is left), while the counters keep the amounts.
 */
#include <errno.h>
#include <stdlib.h>

#include "core/co_internal.h"
#include "core/commfault.h"
#include "core/emcy.h"
#include "core/nmt.h"

#define QUIET_MAX_MS 3600000u

/* ends by silence (true) or by the controller's state */
static const bool ends_by_silence[CO_COMM_FAULT_COUNT] = {
	[CO_COMM_FAULT_ID_COLLISION] = true,
	[CO_COMM_FAULT_RX_OVERRUN] = true,
	[CO_COMM_FAULT_TX_LOST] = true,
};

/* the controller level a level fault stands for */
static const co_bus_level level_of[CO_COMM_FAULT_COUNT] = {
	[CO_COMM_FAULT_WARNING] = CO_BUS_LEVEL_WARNING,
	[CO_COMM_FAULT_PASSIVE] = CO_BUS_LEVEL_PASSIVE,
	[CO_COMM_FAULT_BUS_OFF] = CO_BUS_LEVEL_BUS_OFF,
};

struct fault {
	co_commfault_stats st;
	uint32_t quiet_ms;
	uint64_t end_us; /* silence-ended faults: end of the episode */
};

struct co_commfault {
	struct fault f[CO_COMM_FAULT_COUNT];
	uint8_t own_id; /* id whose 700h we listen to (LSS may change it) */
	int rx;         /* receiver on 700h + own_id, -1 = none */
};

const char *co_comm_fault_to_string(uint8_t fault)
{
	static const char *const names[CO_COMM_FAULT_COUNT] = {
		"id-collision", "warning", "passive", "bus-off", "rx-overrun", "tx-lost",
	};
	return fault < CO_COMM_FAULT_COUNT ? names[fault] : "?";
}

bool co_commfault_is_errctrl_message(const co_frame *f)
{
	uint8_t state;
	if (f->flags & (CO_FRAME_RTR | CO_FRAME_EXT) || f->len != 1)
		return false;
	state = f->data[0] & 0x7Fu;
	return state == CO_NMT_INITIALISING || state == CO_NMT_STOPPED ||
	       state == CO_NMT_OPERATIONAL || state == CO_NMT_PRE_OPERATIONAL;
}

static void emit(co_node *node, co_comm_fault fault, const struct fault *f)
{
	co_event ev = { .kind = CO_EV_COMM_FAULT };
	ev.u.commfault.fault = (uint8_t)fault;
	ev.u.commfault.active = f->st.active;
	ev.u.commfault.info = f->st.info;
	ev.u.commfault.episodes = f->st.episodes;
	ev.u.commfault.occurrences = f->st.occurrences;
	ev.u.commfault.since_us = f->st.since_us;
	co_node_emit(node, &ev);
}

/* The EMCY a fault raises when its episode begins. */
static void emcy_begin(co_node *node, co_comm_fault fault, uint8_t info, uint64_t now_us)
{
	uint8_t msef[5] = { 0 };
	switch (fault) {
	case CO_COMM_FAULT_ID_COLLISION:
		msef[0] = info;
		(void)co_emcy_send(node, CO_EMCY_CAN_ID_COLLISION, CO_EMCY_REG_COMM, msef, now_us);
		break;
	case CO_COMM_FAULT_PASSIVE:
		(void)co_emcy_send(node, CO_EMCY_CAN_PASSIVE, CO_EMCY_REG_COMM, NULL, now_us);
		break;
	case CO_COMM_FAULT_BUS_OFF:
		/* No EMCY now: nothing can be sent while bus-off. CiA 301:
		 * bus-off is a communication error (1029h:1). */
		(void)co_nmt_comm_error(node, now_us);
		break;
	case CO_COMM_FAULT_RX_OVERRUN:
	case CO_COMM_FAULT_TX_LOST:
		msef[0] = fault == CO_COMM_FAULT_RX_OVERRUN ? 1 : 2;
		(void)co_emcy_send(node, CO_EMCY_CAN_OVERRUN, CO_EMCY_REG_COMM, msef, now_us);
		break;
	default:
		break;
	}
}

static void emcy_end(co_node *node, co_comm_fault fault, uint64_t now_us)
{
	const struct co_commfault *cf = node->commfault;
	switch (fault) {
	case CO_COMM_FAULT_ID_COLLISION:
		(void)co_emcy_clear(node, CO_EMCY_CAN_ID_COLLISION, now_us);
		break;
	case CO_COMM_FAULT_PASSIVE:
		(void)co_emcy_clear(node, CO_EMCY_CAN_PASSIVE, now_us);
		break;
	case CO_COMM_FAULT_BUS_OFF:
		/* 8140h says it happened; it is over, so no error stays */
		(void)co_emcy_send(node, CO_EMCY_BUS_OFF_RECOVERED, CO_EMCY_REG_COMM, NULL, now_us);
		(void)co_emcy_clear(node, CO_EMCY_BUS_OFF_RECOVERED, now_us);
		break;
	case CO_COMM_FAULT_RX_OVERRUN:
	case CO_COMM_FAULT_TX_LOST:
		if (!cf->f[CO_COMM_FAULT_RX_OVERRUN].st.active &&
		    !cf->f[CO_COMM_FAULT_TX_LOST].st.active)
			(void)co_emcy_clear(node, CO_EMCY_CAN_OVERRUN, now_us);
		break;
	default:
		break;
	}
}

/* bus_off: the controller is bus-off, nothing can be sent: the episode
 * begins without its EMCY (bus-off's own reaction still runs). */
static void episode_begin(co_node *node, co_comm_fault fault, bool bus_off, uint64_t now_us)
{
	struct fault *f = &node->commfault->f[fault];
	f->st.active = true;
	f->st.episodes++;
	f->st.since_us = now_us;
	if (!bus_off || fault == CO_COMM_FAULT_BUS_OFF)
		emcy_begin(node, fault, f->st.info, now_us);
	emit(node, fault, f);
}

static void episode_end(co_node *node, co_comm_fault fault, uint64_t now_us)
{
	struct fault *f = &node->commfault->f[fault];
	f->st.active = false;
	f->end_us = CO_NO_DEADLINE;
	emcy_end(node, fault, now_us);
	emit(node, fault, f);
}

int co_commfault_occurred(co_node *node, co_comm_fault fault, uint32_t count, uint64_t now_us)
{
	struct co_commfault *cf = node->commfault;
	struct fault *f;
	if (!cf)
		return -ENODEV;
	if ((unsigned)fault >= CO_COMM_FAULT_COUNT || !ends_by_silence[fault] || count == 0)
		return -EINVAL;
	f = &cf->f[fault];
	f->st.occurrences += count;
	f->st.last_us = now_us;
	f->end_us = now_us + (uint64_t)f->quiet_ms * 1000u;
	co_node_deadline_lower(node, f->end_us);
	if (!f->st.active)
		episode_begin(node, fault, cf->f[CO_COMM_FAULT_BUS_OFF].st.active, now_us);
	return 0;
}

int co_commfault_bus_state(co_node *node, co_bus_level level, uint64_t now_us)
{
	struct co_commfault *cf = node->commfault;
	if (!cf)
		return -ENODEV;
	/* Worst first when it gets worse (passive before bus-off), mildest
	 * first when it gets better, so the EMCYs tell the way it went. */
	for (unsigned i = 0; i < CO_COMM_FAULT_COUNT; i++) {
		co_comm_fault fault = (co_comm_fault)i;
		struct fault *f = &cf->f[fault];
		if (ends_by_silence[fault] || f->st.active || level < level_of[fault])
			continue;
		f->st.occurrences++;
		f->st.last_us = now_us;
		episode_begin(node, fault, level == CO_BUS_LEVEL_BUS_OFF, now_us);
	}
	for (unsigned i = CO_COMM_FAULT_COUNT; i-- > 0;) {
		co_comm_fault fault = (co_comm_fault)i;
		if (!ends_by_silence[fault] && cf->f[fault].st.active && level < level_of[fault])
			episode_end(node, fault, now_us);
	}
	return 0;
}

int co_commfault_set_quiet_ms(co_node *node, co_comm_fault fault, uint32_t quiet_ms)
{
	if (!node->commfault)
		return -ENODEV;
	if ((unsigned)fault >= CO_COMM_FAULT_COUNT || !ends_by_silence[fault] || quiet_ms == 0 ||
	    quiet_ms > QUIET_MAX_MS)
		return -EINVAL;
	node->commfault->f[fault].quiet_ms = quiet_ms;
	return 0;
}

const co_commfault_stats *co_commfault_get(const co_node *node, co_comm_fault fault)
{
	if (!node->commfault || (unsigned)fault >= CO_COMM_FAULT_COUNT)
		return NULL;
	return &node->commfault->f[fault].st;
}

void co_commfault_reset_counters(co_node *node)
{
	if (!node->commfault)
		return;
	for (unsigned i = 0; i < CO_COMM_FAULT_COUNT; i++) {
		node->commfault->f[i].st.episodes = 0;
		node->commfault->f[i].st.occurrences = 0;
	}
}

/* ---- the node-ID collision ------------------------------------------------ */

static void own_id_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	(void)arg;
	if (!co_commfault_is_errctrl_message(f))
		return; /* a remote request is someone guarding us */
	node->commfault->f[CO_COMM_FAULT_ID_COLLISION].st.info = f->data[0];
	(void)co_commfault_occurred(node, CO_COMM_FAULT_ID_COLLISION, 1, now_us);
}

/* Listen on 700h + our node-ID (none while LSS-unconfigured). */
static int listen_own_id(co_node *node)
{
	struct co_commfault *cf = node->commfault;
	if (cf->rx >= 0)
		(void)co_rx_unregister(node, cf->rx);
	cf->rx = -1;
	cf->own_id = node->node_id;
	if (cf->own_id < 1 || cf->own_id > 127)
		return 0;
	cf->rx = co_rx_register(node, CO_NMT_ERRCTRL_BASE + cf->own_id, 0, own_id_rx, NULL);
	return cf->rx < 0 ? cf->rx : 0;
}

/* ---- service --------------------------------------------------------------- */

static int commfault_init(co_node *node)
{
	struct co_commfault *cf = calloc(1, sizeof(*cf));
	if (!cf)
		return -ENOMEM;
	node->commfault = cf;
	cf->rx = -1;
	for (unsigned i = 0; i < CO_COMM_FAULT_COUNT; i++) {
		cf->f[i].end_us = CO_NO_DEADLINE;
		cf->f[i].quiet_ms = i == CO_COMM_FAULT_ID_COLLISION
					    ? CO_COMMFAULT_ID_COLLISION_QUIET_MS
					    : CO_COMMFAULT_LOST_QUIET_MS;
	}
	return listen_own_id(node);
}

static void commfault_fini(co_node *node)
{
	free(node->commfault);
	node->commfault = NULL;
}

static uint64_t commfault_tick(co_node *node, uint64_t now_us)
{
	struct co_commfault *cf = node->commfault;
	uint64_t next = CO_NO_DEADLINE;
	for (unsigned i = 0; i < CO_COMM_FAULT_COUNT; i++) {
		struct fault *f = &cf->f[i];
		if (f->st.active && ends_by_silence[i] && now_us >= f->end_us)
			episode_end(node, (co_comm_fault)i, now_us);
		if (f->st.active && ends_by_silence[i] && f->end_us < next)
			next = f->end_us;
	}
	return next;
}

static void commfault_reset_comm(co_node *node, uint64_t now_us)
{
	(void)now_us;
	/* The episodes go on (the bus did not change), and so do their
	 * active errors in the EMCY service. LSS may have given us another
	 * node-ID. */
	if (node->node_id != node->commfault->own_id)
		(void)listen_own_id(node);
}

const co_service co_svc_commfault = {
	.name = "commfault",
	.init = commfault_init,
	.fini = commfault_fini,
	.tick = commfault_tick,
	.reset_comm = commfault_reset_comm,
};
