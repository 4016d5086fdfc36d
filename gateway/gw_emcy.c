/* SPDX-License-Identifier: MIT */
/*
 * gateway/gw_emcy.c - EMCY routing at run time (CiA 302-7, 1F2Fh): an EMCY
 * this line consumed goes, as a message, to the lines of the networks its
 * 1F2Fh entry names (the plan: gateway/emcy_route.h); an EMCY handed to
 * this line goes out with the line's own EMCY COB-ID (docs/gateway.md).
 */
#include "core/od.h"
#include "gateway/convention.h"
#include "gateway/emcy_route.h"
#include "gateway/gw_line.h"
#include "mailbox/server.h"

void gw_emcy_consumed(struct gw_line *gl, const co_ev_emcy *e)
{
	uint32_t bits = 0;
	gw_emcy_plan plan;
	gw_msg m = { .kind = M_EMCY, .net = gl->p.network_id, .node = e->node, .code = e->code };

	if (co_od_get_u32(co_node_od(gl->node), GW_OBJ_EMCY_ROUTES, e->node, &bits) || !bits)
		return;
	GW_COUNT(gl->c.emcy.consumed);
	/* An EMCY another router forwarded keeps its origin (bytes 3..7). */
	if (e->code == GW_EMCY_FWD_CODE) {
		m.net = co_get_le16(&e->msef[0]);
		m.node = e->msef[2];
		m.code = co_get_le16(&e->msef[3]);
	}
	gw_emcy_route_plan(&gl->routes, bits, &plan);
	__atomic_fetch_add(&gl->c.emcy.unroutable, plan.unknown + plan.loops, __ATOMIC_RELAXED);
	mbx_ev_gw_emcy ev = { .src_net = m.net, .src_node = m.node, .code = m.code };
	for (unsigned j = 0; j < gl->g->n; j++) {
		if (!(plan.lines & (1u << j)) || gl->g->line[j].p.network_id == m.net)
			continue; /* never back into the network it came from */
		if (gw_send_to(gl, j, &m)) {
			GW_COUNT(gl->c.emcy.dropped);
		} else {
			GW_COUNT(gl->c.emcy.forwarded);
			ev.lines |= (uint16_t)(1u << j);
		}
	}
	if (ev.lines)
		mbx_server_publish(line_mbx(gl->l), MBX_EV_GW_EMCY, 0, &ev, sizeof ev);
}

void gw_emcy_send(struct gw_line *gl, const gw_msg *m)
{
	co_od *od = co_node_od(gl->node);
	gw_emcy_fwd fwd = { .src_net = m->net, .src_node = m->node, .code = m->code };
	uint32_t cob;
	co_frame f;

	/* Our own EMCY COB-ID on this line (1014h), outside our 1003h. */
	if (co_od_get_u32(od, 0x1014, 0, &cob) || (cob & 0x80000000u)) {
		GW_COUNT(gl->c.emcy.dropped);
		return;
	}
	co_od_get_u8(od, 0x1001, 0, &fwd.err_reg);
	uint32_t id;
	uint8_t flags;
	co_cob_split(cob, &id, &flags);
	co_frame_init(&f, id, 8);
	f.flags |= flags;
	gw_emcy_fwd_encode(f.data, &fwd);
	if (co_node_send(gl->node, &f) == 0)
		GW_COUNT(gl->c.emcy.sent);
}
