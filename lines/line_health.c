/* SPDX-License-Identifier: MIT */
/*
 * lines/line_health.c - the bus health of the line (docs/troubleshooting.md):
 * what the CAN port sees (error frames, controller states, frames lost on
 * receive and on transmit, the transmit queue's watermarks) goes to the
 * node's communication faults (core/commfault.h: episodes, CiA 301 EMCYs),
 * their episodes to the log and to subscribers (MBX_EV_COMM_FAULT), and
 * the counters to LINE_HEALTH, which a client with write rights resets
 * with LINE_HEALTH_RESET.
 *
 * Bus-off recovery is the driver's (`ip link set CAN type can restart-ms
 * N`, docs/troubleshooting.md): the line never restarts the controller
 * itself; it reports the restart the driver signals (CAN_ERR_RESTARTED)
 * and then the end of the episode, EMCY 8140h.
 *
 * Line thread only.
 */
#include "lines/line_internal.h"

#include <linux/can/error.h>
#include <string.h>

#include "core/commfault.h"
#include "lines/log.h"

static co_bus_level level_of(can_bus_state s)
{
	switch (s) {
	case CAN_BUS_WARNING:
		return CO_BUS_LEVEL_WARNING;
	case CAN_BUS_PASSIVE:
		return CO_BUS_LEVEL_PASSIVE;
	case CAN_BUS_OFF:
		return CO_BUS_LEVEL_BUS_OFF;
	default:
		return CO_BUS_LEVEL_ACTIVE;
	}
}

static void publish_fault(line *l, uint8_t fault, bool active, uint8_t info, uint32_t episodes,
			  uint32_t occurrences)
{
	mbx_ev_comm_fault ev = {
		.fault = fault,
		.active = active,
		.info = info,
		.can_state = line_mbx_can_state(can_port_bus_state(l->port)),
		.episodes = episodes,
		.occurrences = occurrences,
	};
	mbx_server_publish(l->mbx, MBX_EV_COMM_FAULT, 0, &ev, sizeof ev);
}

/* What the log says when an episode begins, and what to look at. */
static const char *fault_hint(uint8_t fault)
{
	switch (fault) {
	case MBX_FAULT_ID_COLLISION:
		return "another device sends boot-up/heartbeat on our node-ID (EMCY 8150h)";
	case MBX_FAULT_WARNING:
		return "error counters at the warning limit: check wiring and termination";
	case MBX_FAULT_PASSIVE:
		return "error passive (EMCY 8120h): check termination, cable, bit rate";
	case MBX_FAULT_BUS_OFF:
		return "bus-off: nothing is sent until the driver restarts the controller";
	case MBX_FAULT_RX_OVERRUN:
		return "received frames lost (EMCY 8110h): the line cannot keep up";
	case MBX_FAULT_TX_LOST:
		return "frames not delivered (EMCY 8110h): no ACK (no other node, cable), "
		       "transmit time-out or the queue full";
	case MBX_FAULT_LINK_DOWN:
		return "the interface is down";
	default:
		return "transmit queue above its high-water mark";
	}
}

void line_health_on_fault(line *l, const co_ev_commfault *f)
{
	const co_commfault_stats *st = co_commfault_get(l->node, (co_comm_fault)f->fault);
	if (f->active)
		cogw_log(COGW_LOG_WARNING, "line %s (%s): %s begins: %s", l->name, l->ifname,
			 co_comm_fault_to_string(f->fault), fault_hint(f->fault));
	else
		cogw_log(COGW_LOG_NOTICE, "line %s (%s): %s over (%u in this episode's counters)",
			 l->name, l->ifname, co_comm_fault_to_string(f->fault),
			 st ? st->occurrences : 0);
	publish_fault(l, f->fault, f->active, f->info, f->episodes, f->occurrences);
}

void line_on_can_error(line *l, const can_rx_item *it)
{
	const can_error_info *e = &it->error;
	struct line_health *h = &l->health;
	if (e->raw_class & CAN_ERR_CNT) {
		h->tec = e->tx_errors;
		h->rec = e->rx_errors;
	}
	if (e->restarted)
		h->restarts++;
	if (e->state_changed) {
		can_bus_state prev = e->restarted ? CAN_BUS_OFF : l->bus_state_prev;
		cogw_log(e->state == CAN_BUS_ACTIVE ? COGW_LOG_NOTICE : COGW_LOG_WARNING,
			 "line %s (%s): CAN controller %s -> %s", l->name, l->ifname,
			 can_bus_state_to_string(prev), can_bus_state_to_string(e->state));
		mbx_ev_can_state ev = { .state = line_mbx_can_state(e->state),
					.prev = line_mbx_can_state(prev),
					.tec = e->tx_errors,
					.rec = e->rx_errors };
		mbx_server_publish(l->mbx, MBX_EV_CAN_STATE, 0, &ev, sizeof ev);
		co_commfault_bus_state(l->node, level_of(e->state), l->now_us);
		l->bus_state_prev = e->state;
		l->link_events++;
	}
	if (e->rx_overflow)
		co_commfault_occurred(l->node, CO_COMM_FAULT_RX_OVERRUN, 1, l->now_us);
	if (e->tx_overflow || e->no_ack || e->tx_timeout)
		co_commfault_occurred(l->node, CO_COMM_FAULT_TX_LOST, 1, l->now_us);
}

/* The transmit queue's watermarks: an episode of the line's own, no EMCY
 * (nothing is lost yet; when something is, TX_LOST says so). */
static void tx_pressure(line *l, int crossing)
{
	struct line_health *h = &l->health;
	if (crossing > 0 && !h->pressure_active) {
		h->pressure_active = true;
		h->pressure_episodes++;
		h->pressure_last_us = l->now_us;
		h->pressure_seen = true;
	} else if (crossing < 0 && h->pressure_active) {
		h->pressure_active = false;
	} else {
		return;
	}
	cogw_log(crossing > 0 ? COGW_LOG_WARNING : COGW_LOG_INFO,
		 "line %s: transmit queue %s (%zu frames queued)", l->name,
		 crossing > 0 ? "above its high-water mark" : "back below its low-water mark",
		 can_port_tx_queued(l->port));
	publish_fault(l, MBX_FAULT_TX_PRESSURE, h->pressure_active, 0, h->pressure_episodes,
		      h->pressure_episodes);
}

void line_health_poll(line *l)
{
	struct line_health *h = &l->health;
	const can_port_stats *cs = can_port_get_stats(l->port);
	uint64_t tx_lost = cs->tx_drops + cs->tx_errors;
	if (cs->rx_overflow_drops != h->seen_rx_drops) {
		uint64_t n = cs->rx_overflow_drops - h->seen_rx_drops;
		h->seen_rx_drops = cs->rx_overflow_drops;
		co_commfault_occurred(l->node, CO_COMM_FAULT_RX_OVERRUN,
				      n > UINT32_MAX ? UINT32_MAX : (uint32_t)n, l->now_us);
	}
	if (tx_lost != h->seen_tx_lost) {
		uint64_t n = tx_lost - h->seen_tx_lost;
		h->seen_tx_lost = tx_lost;
		co_commfault_occurred(l->node, CO_COMM_FAULT_TX_LOST,
				      n > UINT32_MAX ? UINT32_MAX : (uint32_t)n, l->now_us);
	}
	int wm = can_port_take_watermark_event(l->port);
	if (wm)
		tx_pressure(l, wm);
}

static uint32_t age_ms(uint64_t now_us, uint64_t last_us, bool seen)
{
	uint64_t ms;
	if (!seen)
		return UINT32_MAX;
	ms = (now_us - last_us) / 1000u;
	return ms >= UINT32_MAX ? UINT32_MAX - 1 : (uint32_t)ms;
}

void line_health(line *l, const mbx_request *req)
{
	const struct line_health *h = &l->health;
	const can_port_stats *cs = can_port_get_stats(l->port);
	mbx_line_health out;
	memset(&out, 0, sizeof out);
	out.can_state = line_mbx_can_state(can_port_bus_state(l->port));
	out.n_faults = MBX_FAULT_COUNT;
	out.tec = h->tec;
	out.rec = h->rec;
	out.restarts = h->restarts;
	out.id_collision_quiet_ms = l->p.id_conflict_quiet_ms;
	out.lost_quiet_ms = l->p.fault_quiet_ms;
	out.rx_overflow_drops = cs->rx_overflow_drops - h->base_rx_drops;
	out.tx_dropped = cs->tx_drops - h->base_tx_drops;
	out.tx_errors = cs->tx_errors - h->base_tx_errors;
	out.tx_queued_max = cs->tx_queued_max;
	for (unsigned i = 0; i < CO_COMM_FAULT_COUNT; i++) {
		const co_commfault_stats *st = co_commfault_get(l->node, (co_comm_fault)i);
		mbx_fault_counters *fc = &out.fault[i];
		if (!st)
			continue;
		fc->active = st->active;
		fc->info = st->info;
		fc->episodes = st->episodes;
		fc->occurrences = st->occurrences;
		fc->age_ms = age_ms(l->now_us, st->last_us, st->last_us != 0);
	}
	mbx_fault_counters *p = &out.fault[MBX_FAULT_TX_PRESSURE];
	p->active = h->pressure_active;
	p->episodes = h->pressure_episodes;
	p->occurrences = h->pressure_episodes;
	p->age_ms = age_ms(l->now_us, h->pressure_last_us, h->pressure_seen);
	const struct line_link *k = &l->link;
	mbx_fault_counters *d = &out.fault[MBX_FAULT_LINK_DOWN];
	d->active = k->down;
	d->episodes = k->episodes;
	d->occurrences = k->episodes;
	d->age_ms = age_ms(l->now_us, k->since_us, k->since_us != 0);
	out.reopens = k->reopens;
	out.last_outage_ms = k->last_outage_ms;
	line_answer(l, &req->reply, 0, 0, &out, sizeof out);
}

void line_health_reset(line *l, const mbx_request *req)
{
	struct line_health *h = &l->health;
	const can_port_stats *cs = can_port_get_stats(l->port);
	co_commfault_reset_counters(l->node);
	h->restarts = 0;
	h->pressure_episodes = 0;
	l->link.episodes = 0;
	l->link.reopens = 0;
	h->base_rx_drops = cs->rx_overflow_drops;
	h->base_tx_drops = cs->tx_drops;
	h->base_tx_errors = cs->tx_errors;
	cogw_log(COGW_LOG_INFO, "line %s: bus health counters reset (uid %u, pid %u)", l->name,
		 req->uid, req->pid);
	line_answer(l, &req->reply, 0, 0, NULL, 0);
}

int line_health_attach(line *l)
{
	int rc;
	if ((rc = co_commfault_set_quiet_ms(l->node, CO_COMM_FAULT_ID_COLLISION,
					    l->p.id_conflict_quiet_ms)) < 0 ||
	    (rc = co_commfault_set_quiet_ms(l->node, CO_COMM_FAULT_RX_OVERRUN,
					    l->p.fault_quiet_ms)) < 0 ||
	    (rc = co_commfault_set_quiet_ms(l->node, CO_COMM_FAULT_TX_LOST, l->p.fault_quiet_ms)) <
		    0)
		cogw_log(COGW_LOG_ERR, "line %s: quiet times %u/%u ms refused", l->name,
			 l->p.id_conflict_quiet_ms, l->p.fault_quiet_ms);
	return rc;
}
