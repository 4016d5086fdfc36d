/* SPDX-License-Identifier: MIT */
/*
 * gateway/gateway.h - the CiA 302-7 gateway at run time: one extension per
 * line (lines/line_ext.h) and what the lines share (the process image, the
 * mesh of cross-line rings).
 *
 * On every line the extension
 * - takes network indications on the line's SDO server (routing hook,
 *   core/sdo_server.h) and runs one routed session per server channel
 *   (gateway/sdo_route.h), resolving the network in the line's 1F2Ch;
 * - lends SDO client channels of its pool to sessions of other lines
 *   (relay leases, core/sdo_client.h) and relays their frames;
 * - forwards consumed EMCYs per 1F2Fh and sends those forwarded to it;
 * - publishes B-objects written on it (by its RPDOs, over SDO, by mailbox
 *   clients: an after_write hook) into the shared image and hands each
 *   update, value included, to the lines whose TPDOs map it; applies the
 *   updates of other lines to its own OD, triggering its TPDOs (after a
 *   drop, the image's latest value); an event-driven TPDO of another line
 *   that may go at once it sends itself, in the same wake-up
 *   (gateway/fast_tpdo.h, docs/gateway.md "One wake-up per hop");
 * - serves the mailbox's GW_ROUTES (the routing table with its counters)
 *   and is the routing step of the line's mailbox SDO transfers with a
 *   node of any network (MBX_CMD_GW_SDO_*, lines/line_sdo.c): the transfer
 *   runs on this line's SDO client, its frames go through a relay lease
 *   of the line the route names (after a network indication to the next
 *   router when the network lies further away).
 * Lines talk only through the rings (one per ordered pair, lines/xring.h):
 * a full or closed ring is a counted drop, and a routed request that
 * cannot be handed off is refused with GW_AB_ROUTE_BUSY.
 *
 * Threads: gw_create/gw_destroy and gw_line_ext on the main thread, before
 * the lines start / after they stopped; gw_line_counters from any thread
 * (relaxed reads of counters only the line thread writes); everything else
 * runs on the line threads through the ops.
 */
#ifndef COGW_GATEWAY_GATEWAY_H
#define COGW_GATEWAY_GATEWAY_H

#include <stdint.h>

#include "core/od.h"
#include "gateway/emcy_route.h"
#include "lines/line_ext.h"

typedef struct gw gw;

#define GW_PINNED_MAX 64u

typedef struct gw_line_params {
	uint16_t network_id;     /* this line's network */
	uint32_t sdo_timeout_ms; /* per frame, toward requesters and targets */
	/* B-objects (sub 0) this line takes from the image whether or not a
	 * TPDO of its own maps them: the device object layer forwards them
	 * to a device (gateway.forward, docs/gateway.md) */
	uint16_t pinned[GW_PINNED_MAX];
	uint8_t n_pinned;
} gw_line_params;

typedef struct gw_params {
	unsigned n_lines; /* 1..GW_LINES_MAX */
	gw_line_params line[GW_LINES_MAX];
	const co_od *image_od; /* the B000h..BFFFh objects to share
	                                * (any line's OD: they are the same) */
	uint32_t ring_slots;   /* per ordered pair of lines (default 1024) */
} gw_params;

/* Counters of one line (published as relaxed atomics). */
typedef struct gw_line_counters {
	uint64_t sessions; /* network indications taken */
	uint64_t routed;   /* transfers completed */
	uint64_t aborted, timed_out, refused;
	uint64_t relayed_frames; /* frames through leases of this line */
	uint64_t pdo_published;  /* B-object writes put into the image */
	uint64_t pdo_forwarded;  /* updates handed to other lines */
	uint64_t pdo_dropped;    /* updates lost (ring full / closed) */
	uint64_t pdo_applied;    /* updates applied to this line's OD */
	uint64_t pdo_triggered;  /* of those, with a TPDO to send */
	uint64_t pdo_fast;       /* TPDO frames of other lines this line sent
	                          * in the wake-up that wrote the value */
	gw_emcy_counters emcy;
	uint64_t ring_drops; /* other hand-offs lost */
	uint64_t sdo_across; /* frames of routed SDO transfers this line sent
	                      * on another line's interface */
} gw_line_counters;

int gw_create(gw **out, const gw_params *p);
void gw_destroy(gw *g); /* accepts NULL */
/* The extension of line i: ops, ctx and the wake eventfd of its rings. */
void gw_line_ext(gw *g, unsigned line_no, line_ext *out);
void gw_line_counters_get(gw *g, unsigned line_no, gw_line_counters *out);

#endif /* COGW_GATEWAY_GATEWAY_H */
