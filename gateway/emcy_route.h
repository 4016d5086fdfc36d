/* SPDX-License-Identifier: MIT */
/*
 * gateway/emcy_route.h - EMCY routing (1F2Fh): where an EMCY consumed on a
 * line through 1028h:n is re-sent.
 *
 * 1F2Fh:n names target networks (bit k-1 = network k). Each network is
 * looked up in the consuming line's routing table: a network attached to
 * another line gets the forwarded EMCY on that line; a network further
 * away gets it on the line of its next router (which forwards it by its
 * own 1F2Fh). A line is sent to once however many networks lead there;
 * the consuming line itself never (no echo), and unknown networks are
 * counted, not guessed.
 *
 * Pure decision; the line that sends builds the frame (convention.h) from
 * its own 1014h/1001h, outside its 1003h error history.
 */
#ifndef COGW_GATEWAY_EMCY_ROUTE_H
#define COGW_GATEWAY_EMCY_ROUTE_H

#include <stdint.h>

#include "gateway/route.h"

typedef struct gw_emcy_plan {
	uint16_t lines;  /* bit L set: send the forwarded EMCY on line L */
	uint8_t unknown; /* networks named but not reachable */
	uint8_t loops;   /* networks whose route is the consuming line */
} gw_emcy_plan;

/* Counters a line keeps for EMCY routing. */
typedef struct gw_emcy_counters {
	uint64_t consumed;   /* EMCYs looked at (1F2Fh entry non-zero) */
	uint64_t forwarded;  /* forwarded frames handed to another line */
	uint64_t unroutable; /* networks named without a usable route */
	uint64_t dropped;    /* hand-offs lost (target line's ring full) */
	uint64_t sent;       /* forwarded EMCYs this line sent on its bus */
} gw_emcy_counters;

/* Plan the forwarding of an EMCY consumed on t->own_line whose 1F2Fh
 * entry is bits. Returns plan.lines (0 = nowhere). */
uint16_t gw_emcy_route_plan(const gw_route_table *t, uint32_t bits, gw_emcy_plan *plan);

#endif /* COGW_GATEWAY_EMCY_ROUTE_H */
