/* SPDX-License-Identifier: MIT */
/*
 * gateway/gw_mbx_hop.c - the routing step of a mailbox SDO transfer with
 * a node of a network (MBX_CMD_GW_SDO_*; lines/line_sdo.c owns the
 * transfer, line_ext.h sdo_route is the seam).
 *
 *   1. gw_hop_route()   resolve the network in this line's 1F2Ch. Its own
 *                       network, or a network attached to this line: the
 *                       transfer talks to the node on this line's bus.
 *                       Otherwise a hop: the transfer runs on this line's
 *                       SDO client, its frames go to hop_relay().
 *   2. hop_relay()      the transfer's first frame reserves a relay lease
 *                       on the line the route names (gw_lease_open, the
 *                       same check as a routed session's) and follows it
 *                       (M_TO_TARGET); behind a router, the network
 *                       indication goes first and the first frame waits
 *                       for the router's confirmation.
 *   3. gw_hop_*()       what comes back: the lease refused (at once, by
 *                       the reservation, through this line's own queue),
 *                       the line lost its link or could not bind the lease
 *                       (M_LOST), a router refused: the transfer is
 *                       cancelled with that abort; the server's frames go
 *                       to the SDO client (sdo_client_relay_recv).
 *   4. gw_hop_end()     the transfer ended (line_sdo's confirmation, also
 *                       after a client went away): the lease is given
 *                       back (M_CLOSE).
 * The hop never touches the other line's state: everything crosses as a
 * gw_msg, by value, through the rings.
 */
#include <string.h>

#include "core/sdo_client.h"
#include "gateway/convention.h"
#include "gateway/gw_line.h"

static uint32_t sid_of(const struct gw_mbx_hop *h)
{
	uint32_t slot = (uint32_t)(h - h->gl->hops);

	return (uint32_t)h->gl->idx << 24 | GW_SID_HOP | slot << 16 | h->gen;
}

static struct gw_mbx_hop *hop_by_sid(struct gw_line *gl, uint32_t sid)
{
	uint32_t slot = (sid >> 16) & 0x7Fu;

	if ((sid >> 24) != gl->idx || !(sid & GW_SID_HOP) || slot >= GW_HOPS_MAX ||
	    gl->hops[slot].phase == HOP_FREE || gl->hops[slot].gen != (uint16_t)sid)
		return NULL;
	return &gl->hops[slot];
}

static struct gw_mbx_hop *hop_by_tag(struct gw_line *gl, uint64_t tag)
{
	for (unsigned i = 0; i < GW_HOPS_MAX; i++)
		if (gl->hops[i].phase != HOP_FREE && gl->hops[i].tag == tag)
			return &gl->hops[i];
	return NULL;
}

static void hop_send(struct gw_mbx_hop *h, gw_msg *m)
{
	m->sid = sid_of(h);
	m->channel = h->lease_ch;
	if (gw_send_to(h->gl, h->hop.line, m))
		GW_COUNT(h->gl->c.ring_drops); /* the transfer's timeout ends it */
}

static void hop_frame(struct gw_mbx_hop *h, const uint8_t d[8])
{
	gw_msg m = { .kind = M_TO_TARGET };

	h->target_aborted = (d[0] >> 5) == SDO_CCS_ABORT;
	memcpy(m.d, d, 8);
	hop_send(h, &m);
}

/* Step 2: a frame of the transfer (from inside the SDO client: nothing
 * here calls back into it). */
static void hop_relay(void *ctx, const uint8_t d[8])
{
	struct gw_mbx_hop *h = ctx;
	gw_msg lost = { .kind = M_LOST, .sid = sid_of(h) };
	uint8_t ind[8];

	switch (h->phase) {
	case HOP_ROUTED:
		lost.abort = gw_lease_open(h->gl, &h->hop, sid_of(h), &h->lease_ch, 0, 0);
		if (lost.abort) {
			/* refused: the cancel may not come from inside the client,
			 * so through this line's own queue (gw_hop_lost) */
			h->unleased = true;
			h->held_valid = false;
			h->phase = HOP_INDICATING;
			if (gw_send_to(h->gl, h->gl->idx, &lost))
				GW_COUNT(h->gl->c.ring_drops); /* the transfer's timeout ends it */
		} else if (h->hop.via_router) {
			gw_netind_encode(ind, (gw_netind){ h->net, h->node });
			hop_frame(h, ind);
			memcpy(h->held, d, 8);
			h->held_valid = true;
			h->phase = HOP_INDICATING;
		} else {
			hop_frame(h, d);
			h->phase = HOP_RELAYING;
		}
		break;
	case HOP_INDICATING:
		h->held_valid = false; /* the transfer gave up (its abort) */
		break;
	case HOP_RELAYING:
		hop_frame(h, d);
		break;
	default:
		break; /* refused: the cancel's own abort frame */
	}
}

/* Step 1. */
uint32_t gw_hop_route(void *ctx, line *l, uint64_t tag, uint16_t net, uint8_t node,
		      line_sdo_route *out)
{
	struct gw_line *gl = ctx;
	gw_hop hop = { .line = (uint8_t)gl->idx, .node = node };
	struct gw_mbx_hop *h = NULL;
	uint32_t abort = 0;

	(void)l;
	if (net != gl->p.network_id)
		abort = gw_route_resolve(&gl->routes, net, node, -1, &hop);
	if (abort)
		return abort;
	out->node = node;
	if (hop.line == gl->idx && !hop.via_router)
		return 0; /* on this line's bus */
	for (unsigned i = 0; i < GW_HOPS_MAX && !h; i++)
		if (gl->hops[i].phase == HOP_FREE)
			h = &gl->hops[i];
	if (!h)
		return GW_AB_ROUTE_BUSY;
	h->gl = gl;
	h->gen++;
	h->phase = HOP_ROUTED;
	h->unleased = h->lease_lost = h->target_aborted = false;
	h->held_valid = false;
	h->net = net;
	h->node = node;
	h->tag = tag;
	h->hop = hop;
	out->relay = hop_relay;
	out->relay_ctx = h;
	out->relay_target = (uint32_t)net << 8 | node;
	return 0;
}

/* Step 3: the route ends the transfer with `abort`. */
static void hop_refuse(struct gw_mbx_hop *h, uint32_t abort, uint64_t now_us)
{
	h->phase = HOP_REFUSED;
	h->held_valid = false;
	sdo_client_cancel_tag(h->gl->node, h->tag, abort, now_us);
}

void gw_hop_target_frame(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	struct gw_mbx_hop *h = hop_by_sid(gl, m->sid);
	const uint8_t *d = m->d;

	if (!h)
		return;
	if (h->phase == HOP_RELAYING) {
		sdo_client_relay_recv(gl->node, h->tag, d, now_us);
		return;
	}
	if (h->phase != HOP_INDICATING)
		return;
	/* The router's answer to the network indication: a refusal is passed
	 * on unchanged; a confirmation lets the transfer's first frame go to
	 * the server channel that confirmed (docs/gateway.md, multi-hop). */
	if ((d[0] >> 5) == SDO_CCS_ABORT)
		return hop_refuse(h, co_get_le32(&d[4]), now_us);
	if (d[0] != GW_NETIND_CS || co_get_le16(&d[1]) != h->net || d[3] != h->node)
		return hop_refuse(h, SDO_AB_CMD, now_us);
	h->phase = HOP_RELAYING;
	if (h->held_valid)
		hop_frame(h, h->held);
	h->held_valid = false;
}

void gw_hop_lost(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	struct gw_mbx_hop *h = hop_by_sid(gl, m->sid);

	if (!h)
		return;
	h->lease_lost = true;
	if (h->phase != HOP_REFUSED)
		hop_refuse(h, m->abort, now_us);
}

/* Step 4. */
void gw_hop_end(void *ctx, line *l, uint64_t tag)
{
	struct gw_line *gl = ctx;
	struct gw_mbx_hop *h = hop_by_tag(gl, tag);

	(void)l;
	if (!h)
		return; /* on this line's bus: nothing to give back */
	if (h->phase != HOP_ROUTED && !h->unleased)
		gw_lease_close(gl, &h->hop, sid_of(h), h->lease_ch,
			       h->phase == HOP_RELAYING && !h->lease_lost && !h->target_aborted);
	h->phase = HOP_FREE;
}
