/* SPDX-License-Identifier: MIT */
/*
 * gateway/route.h - the routing table of one line (1F2Ch), compiled once
 * when the object changes, with counters per destination network.
 *
 * Every line has its own 1F2Ch: it routes what enters on that line (a
 * network indication on its SDO server, an EMCY consumed through its
 * 1028h) and what mailbox clients of that line ask for. A route that
 * would send a request back on the line it entered through is refused
 * (the requester can reach that network itself, and two routers pointing
 * at each other would otherwise pass a request back and forth).
 *
 * Owned by the line thread of that line; plain data, no locks.
 */
#ifndef COGW_GATEWAY_ROUTE_H
#define COGW_GATEWAY_ROUTE_H

#include <stdbool.h>
#include <stdint.h>

#include "core/od.h"
#include "gateway/convention.h"

typedef enum gw_route_kind {
	GW_ROUTE_NONE = 0, /* not reachable */
	GW_ROUTE_DIRECT,   /* attached to one of our lines */
	GW_ROUTE_ROUTER,   /* further away, through a router on one line */
} gw_route_kind;

const char *gw_route_kind_to_string(gw_route_kind k); /* "none", "direct", "router" */

/* What became of requests for one destination network. */
typedef enum gw_route_outcome {
	GW_OUT_ROUTED = 0, /* the transfer completed */
	GW_OUT_ABORTED,    /* it ended with an abort (either side) */
	GW_OUT_TIMED_OUT,  /* a side went silent */
	GW_OUT_REFUSED,    /* refused at once (no route, loop, line down, busy) */
	GW_OUT_COUNT
} gw_route_outcome;

const char *gw_route_outcome_to_string(gw_route_outcome o);

typedef struct gw_route {
	uint8_t kind;   /* gw_route_kind */
	uint8_t line;   /* 0-based line (kind != NONE) */
	uint8_t router; /* next router's node-ID (kind == ROUTER) */
	uint32_t raw;   /* the 1F2Ch value it was compiled from */
	uint64_t count[GW_OUT_COUNT];
} gw_route;

typedef struct gw_route_table {
	uint8_t own_line;           /* the line whose 1F2Ch this is */
	uint8_t n_lines;            /* lines of the daemon */
	uint32_t compiles;          /* times the table was compiled */
	uint32_t bad_entries;       /* entries that did not decode (unreachable) */
	gw_route r[GW_NET_MAX + 1]; /* by network; r[0] unused */
} gw_route_table;

/* A resolved next hop. */
typedef struct gw_hop {
	uint8_t line; /* line to send on */
	uint8_t node; /* node to address there: the target itself, or the
	                  * next router (then a network indication goes first) */
	bool via_router;
} gw_hop;

void gw_route_table_init(gw_route_table *t, uint8_t own_line, uint8_t n_lines);

/* Compile from raw[n] = 1F2Ch:n (raw[0] ignored). Entries that do not
 * decode count as unreachable (bad_entries). Counters stay with a network
 * whose route is unchanged and restart for one whose route changed. */
void gw_route_table_compile(gw_route_table *t, const uint32_t raw[GW_NET_MAX + 1]);
/* Same, reading 1F2Ch:1..127 from an OD (missing subs = unreachable). */
void gw_route_table_compile_od(gw_route_table *t, const co_od *od);

/* Resolve a request for (net, node) that entered on from_line (-1 = from
 * a mailbox client, which is on no line). Returns 0 and the hop, or
 * GW_AB_NET_UNKNOWN for no route and for a route back to from_line; a
 * refusal is counted (GW_OUT_REFUSED) on the network. */
uint32_t gw_route_resolve(gw_route_table *t, uint16_t net, uint8_t node, int from_line,
			  gw_hop *out);

/* Count an outcome for a network (ignored for nets outside 1..127). */
void gw_route_count(gw_route_table *t, uint16_t net, gw_route_outcome o);

/* The check_write rule for 1F2Ch:n: 0 or SDO_AB_VALUE (see
 * gw_route_entry_decode). */
uint32_t gw_route_entry_check(uint32_t v, uint8_t n_lines);
/* The whole check of a write to 1F2Ch:n (an SDO or mailbox write at run
 * time, a "values" entry at load time): SDO_AB_TYPE_LEN unless 4 bytes,
 * then gw_route_entry_check. */
uint32_t gw_route_write_check(const co_od_access *a, uint8_t n_lines);

#endif /* COGW_GATEWAY_ROUTE_H */
