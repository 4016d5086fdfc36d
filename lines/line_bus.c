/* SPDX-License-Identifier: MIT */
/*
 * lines/line_bus.c - mailbox commands about the bus itself: LINE_STATUS
 * (controller state, counters), EMCY_SEND (our own emergency), RAW_SEND
 * (frames as given). Answered at once.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <string.h>

#include "core/emcy.h"
#include "core/nmt.h"

void line_status(line *l, const mbx_request *req)
{
	const can_port_stats *cs = can_port_get_stats(l->port);
	const co_node_stats *ns = co_node_get_stats(l->node);
	mbx_line_status st = {
		.can_state = line_mbx_can_state(can_port_bus_state(l->port)),
		.nmt_state = co_nmt_get_state(l->node),
		.node_id = co_node_id(l->node),
		.bitrate = l->p.can.bitrate,
		.rx_frames = cs->rx_frames,
		.tx_frames = cs->tx_frames,
		.rx_dropped = cs->rx_overflow_drops,
		.tx_failed = cs->tx_drops + cs->tx_errors + ns->tx_failed,
		.err_frames = cs->rx_error_frames,
		.bus_off_count = cs->bus_off_count,
		.clients = mbx_server_stats_get(l->mbx)->clients,
		.bus_load_permille = cs->bus_load_permille,
	};
	line_answer(l, &req->reply, 0, 0, &st, sizeof st);
}

void line_emcy_send(line *l, const mbx_request *req)
{
	mbx_emcy_req e;
	memcpy(&e, req->payload, sizeof e);
	int rc = e.code ? co_emcy_send(l->node, e.code, e.reg, e.msef, l->now_us)
			: co_emcy_clear_all(l->node, l->now_us);
	line_answer(l, &req->reply, mbx_status_of_errno(rc), 0, NULL, 0);
}

void line_raw_send(line *l, const mbx_request *req)
{
	size_t n = req->fixed_len / sizeof(mbx_raw_frame);
	for (size_t i = 0; i < n; i++) {
		mbx_raw_frame rf;
		memcpy(&rf, req->payload + i * sizeof rf, sizeof rf);
		co_frame f;
		co_frame_init(&f, rf.id & ~(MBX_RAW_EXT | MBX_RAW_RTR), rf.len);
		if (rf.id & MBX_RAW_EXT)
			f.flags |= CO_FRAME_EXT;
		if (rf.id & MBX_RAW_RTR)
			f.flags |= CO_FRAME_RTR;
		else
			memcpy(f.data, rf.data, rf.len);
		if (co_node_send(l->node, &f) < 0)
			return line_answer(l, &req->reply, MBX_E_BUSY, 0, NULL, 0);
	}
	line_answer(l, &req->reply, 0, 0, NULL, 0);
}
