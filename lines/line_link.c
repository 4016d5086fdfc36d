/* SPDX-License-Identifier: MIT */
/*
 * lines/line_link.c - the line's interface going and coming back
 * (docs/troubleshooting.md "An interface that goes and comes back"): a USB
 * adapter unplugged and plugged in again, or `ip link set can0 down/up`.
 *
 * 1. The kernel tells the line's socket: ENETDOWN when the interface goes
 *    down, ENODEV when it is deleted (the socket is unbound then and would
 *    never receive again). Whichever of receive and send comes first takes
 *    that error, so both report it (a send to an unbound socket: ENXIO).
 *    line_link_lost() begins a `link-down` episode (event, log); the
 *    clients stay registered (the mailbox is no CAN).
 * 2. While down, requests that need the bus are refused at once with
 *    MBX_E_STATE (line_link_refuses), instead of each running into its
 *    own time-out; what only reads or writes the line's own dictionary
 *    goes on.
 * 3. Every LINK_PROBE_US, and at once when a frame comes in on the socket
 *    (line_link_frame_heard: the interface carries frames again, and a
 *    request should not wait for the next look), the line looks at the
 *    interface by name: a
 *    deleted one that is there again is a new interface (another index),
 *    so the port opens a new socket on it with its options and filter
 *    (can_port_reopen) and the line's loop watches that one.
 * 4. Up and running again: the episode ends, the controller counts as
 *    error-active (a new socket knows no older state). The nodes need no
 *    step of their own here: their heartbeats stopped meanwhile, so error
 *    control lost them, and the manager boots each one again when it is
 *    heard again (CiA 302-2, docs/config.md "The manager").
 *
 * Line thread only; each line has its own socket and probe, so a line whose
 * interface is gone touches no other line.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <string.h>

#include "core/commfault.h"
#include "lines/log.h"

#define LINK_PROBE_US 200000u

static void publish(line *l)
{
	const struct line_link *k = &l->link;
	mbx_ev_comm_fault ev = {
		.fault = MBX_FAULT_LINK_DOWN,
		.active = k->down,
		.can_state = line_mbx_can_state(can_port_bus_state(l->port)),
		.episodes = k->episodes,
		.occurrences = k->episodes,
	};
	mbx_server_publish(l->mbx, MBX_EV_COMM_FAULT, 0, &ev, sizeof ev);
}

void line_link_lost(line *l, int err)
{
	struct line_link *k = &l->link;
	l->link_events++;
	if (err == ENODEV || err == ENXIO) /* deleted: the socket is unbound */
		k->reopen = true;
	if (k->down)
		return;
	k->down = true;
	k->episodes++;
	k->since_us = l->now_us;
	k->next_probe_us = l->now_us + LINK_PROBE_US;
	cogw_log(COGW_LOG_WARNING,
		 "line %s (%s): interface %s: requests that need the bus are refused until it "
		 "is back",
		 l->name, l->ifname, k->reopen ? "deleted" : "down");
	publish(l);
}

static void link_back(line *l)
{
	struct line_link *k = &l->link;
	uint64_t ms = (l->now_us - k->since_us) / 1000u;
	k->down = false;
	k->last_outage_ms = ms > UINT32_MAX ? UINT32_MAX : (uint32_t)ms;
	l->link_events++;
	l->bus_state_prev = CAN_BUS_ACTIVE;
	co_commfault_bus_state(l->node, CO_BUS_LEVEL_ACTIVE, l->now_us);
	cogw_log(COGW_LOG_NOTICE, "line %s (%s): interface back after %u ms", l->name, l->ifname,
		 k->last_outage_ms);
	publish(l);
}

void line_link_frame_heard(line *l)
{
	if (l->link.down)
		l->link.next_probe_us = l->now_us;
}

uint64_t line_link_poll(line *l, bool *reopened)
{
	struct line_link *k = &l->link;
	int err = can_port_take_link_error(l->port);
	if (err)
		line_link_lost(l, err);
	if (!k->down)
		return UINT64_MAX;
	if (l->now_us < k->next_probe_us)
		return k->next_probe_us;
	k->next_probe_us = l->now_us + LINK_PROBE_US;
	can_link_state st = can_port_link_state(l->port);
	if (st == CAN_LINK_GONE)
		return k->next_probe_us;
	if (st == CAN_LINK_REPLACED || k->reopen) {
		const char *why = NULL;
		int rc = can_port_reopen(l->port, l->now_us, &why);
		if (rc < 0) {
			cogw_log(COGW_LOG_DEBUG, "line %s (%s): not open again yet: %s: %s",
				 l->name, l->ifname, why ? why : "?", strerror(-rc));
			return k->next_probe_us;
		}
		*reopened = true;
		k->reopen = false;
		k->reopens++;
		cogw_log(COGW_LOG_NOTICE, "line %s (%s): interface created again: new socket",
			 l->name, l->ifname);
		st = can_port_link_state(l->port);
	}
	if (st != CAN_LINK_UP)
		return k->next_probe_us;
	link_back(l);
	return UINT64_MAX;
}

bool line_link_refuses(const line *l, uint16_t code)
{
	return l->link.down && line_cmd_needs_bus(code);
}
