/* SPDX-License-Identifier: MIT */
/*
 * lines/line_nmt.c - mailbox NMT and NODE_TABLE: NMT commands for the
 * network (or the daemon's own node), and the table of remote nodes as the
 * heartbeat consumer and the line's own counters see them.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <string.h>

#include "core/heartbeat.h"
#include "core/nmt.h"

void line_nmt_command(line *l, const mbx_request *req)
{
	mbx_nmt_req n;
	memcpy(&n, req->payload, sizeof n);
	/* Addressed to the daemon's own node-ID: the kernel does not loop our
	 * own frame back to us, so sent on the bus it would change nothing.
	 * Apply it locally instead (e.g. "start" makes the manager OPERATIONAL
	 * so that its RPDOs run and PDO events flow). A vetoed start is a
	 * state refusal. */
	if (n.node == co_node_id(l->node)) {
		int lrc = co_nmt_local_cmd(l->node, n.cs, l->now_us);
		return line_answer(l, &req->reply, mbx_status_of_errno(lrc), 0, NULL, 0);
	}
	int rc = co_nmt_master_send(l->node, n.node, n.cs, l->now_us);
	line_answer(l, &req->reply, mbx_status_of_errno(rc), 0, NULL, 0);
}

static uint8_t hb_code(co_hb_mon mon)
{
	switch (mon) {
	case CO_HB_MON_LOST:
		return 2;
	case CO_HB_MON_ACTIVE:
		return 1;
	case CO_HB_MON_WAITING:
		return 3;
	default:
		return 0;
	}
}

/* The heartbeat consumer is the source of truth for states and times; the
 * line adds what only it counts (boot-ups, EMCYs, line_events.c). */
void line_node_table(line *l, const mbx_request *req)
{
	mbx_node_entry rows[LINE_NODES];
	size_t n = 0;
	for (int i = 1; i < LINE_NODES; i++) {
		const line_node_info *ni = &l->nodes[i];
		uint8_t state = co_hb_remote_state(l->node, (uint8_t)i);
		co_hb_mon mon = co_hb_consumer_status(l->node, (uint8_t)i);
		uint64_t heard = co_hb_last_heard_us(l->node, (uint8_t)i);
		if (state == CO_HB_STATE_UNKNOWN && mon == CO_HB_MON_OFF && !ni->emcy_count &&
		    !ni->duplicate_answers)
			continue;
		uint64_t ago_ms = heard ? (l->now_us - heard) / 1000u : UINT32_MAX;
		rows[n++] = (mbx_node_entry){
			.node = (uint8_t)i,
			.nmt_state = state,
			.hb = hb_code(mon),
			.flags = (uint8_t)((ni->bootups ? 1 : 0) |
					   (ni->emcy_count && ni->last_emcy ? 2 : 0) |
					   (ni->duplicate_answers ? 4 : 0)),
			.last_heard_ms = ago_ms > UINT32_MAX ? UINT32_MAX : (uint32_t)ago_ms,
			.bootups = ni->bootups > UINT16_MAX ? UINT16_MAX : (uint16_t)ni->bootups,
			.last_emcy = ni->last_emcy,
			.emcy_count = ni->emcy_count,
		};
	}
	line_answer(l, &req->reply, 0, 0, rows, n * sizeof rows[0]);
}
