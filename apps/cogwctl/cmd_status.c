/* SPDX-License-Identifier: MIT */
/*
 * cogwctl status: per line the CAN and NMT state, frame and mailbox
 * counters, and the node table (what the line has heard from every node:
 * NMT state from heartbeats/boot-ups, heartbeat supervision, EMCY).
 */
#include <inttypes.h>
#include <string.h>

#include "apps/cogwctl/ctl.h"
#include "core/nmt.h"

static const char *nmt_text(uint8_t s)
{
	return s == 0xFF ? "unknown" : co_nmt_state_to_string(s);
}

static const char *hb_text(uint8_t hb)
{
	return hb == 1 ? "active" : hb == 2 ? "LOST" : hb == 3 ? "waiting" : "not monitored";
}

static int status_line(ctl *c, cogw *h, unsigned line, cJSON *arr)
{
	mbx_line_status st;
	mbx_node_entry nodes[128];
	mbx_stats_wire ms;
	char ctx[64];
	snprintf(ctx, sizeof ctx, "status of line %u", line);
	int rc = cogw_line_status(h, line, &st, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, ctx);
	int n = cogw_node_table(h, line, nodes, 128, c->timeout_ms);
	if (n < 0)
		return ctl_fail(c, n, 0, ctx);
	if (n > 128)
		n = 128;
	rc = cogw_mbx_stats(h, line, &ms, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, ctx);
	/* The gateway's traffic through this line (a daemon without the
	 * gateway answers "unknown command": then there is none to show). */
	mbx_gw_status gw;
	bool has_gw = cogw_gw_routes(h, line, &gw, NULL, 0, NULL, c->timeout_ms) == 0;

	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddNumberToObject(o, "line", line);
		cJSON_AddStringToObject(o, "can_state", mbx_can_state_to_string(st.can_state));
		cJSON_AddNumberToObject(o, "node_id", st.node_id);
		cJSON_AddStringToObject(o, "nmt_state", nmt_text(st.nmt_state));
		cJSON_AddNumberToObject(o, "bitrate", st.bitrate);
		cJSON_AddNumberToObject(o, "bus_load_percent", st.bus_load_permille / 10.0);
		cJSON *cnt = cJSON_AddObjectToObject(o, "counters");
		cJSON_AddNumberToObject(cnt, "rx_frames", (double)st.rx_frames);
		cJSON_AddNumberToObject(cnt, "tx_frames", (double)st.tx_frames);
		cJSON_AddNumberToObject(cnt, "rx_dropped", (double)st.rx_dropped);
		cJSON_AddNumberToObject(cnt, "tx_failed", (double)st.tx_failed);
		cJSON_AddNumberToObject(cnt, "error_frames", (double)st.err_frames);
		cJSON_AddNumberToObject(cnt, "bus_off", (double)st.bus_off_count);
		cJSON *mb = cJSON_AddObjectToObject(o, "mailbox");
		cJSON_AddNumberToObject(mb, "clients", ms.clients);
		cJSON_AddNumberToObject(mb, "commands_ok", (double)ms.commands_ok);
		cJSON_AddNumberToObject(mb, "malformed", (double)ms.malformed);
		cJSON_AddNumberToObject(mb, "access_denied", (double)ms.access_denied);
		cJSON_AddNumberToObject(mb, "events_sent", (double)ms.events_sent);
		cJSON_AddNumberToObject(mb, "dropped", (double)ms.dropped);
		cJSON_AddNumberToObject(mb, "clients_reaped", (double)ms.clients_reaped);
		cJSON_AddNumberToObject(mb, "late_wakes", (double)ms.late_wakes);
		if (has_gw)
			ctl_gw_counters_json(cJSON_AddObjectToObject(o, "gateway"), &gw);
		cJSON *na = cJSON_AddArrayToObject(o, "nodes");
		for (int i = 0; i < n; i++) {
			cJSON *e = cJSON_CreateObject();
			cJSON_AddNumberToObject(e, "node", nodes[i].node);
			cJSON_AddStringToObject(e, "nmt_state", nmt_text(nodes[i].nmt_state));
			cJSON_AddStringToObject(e, "heartbeat",
						nodes[i].hb == 1   ? "active"
						: nodes[i].hb == 2 ? "lost"
						: nodes[i].hb == 3 ? "waiting"
								   : "off");
			if (nodes[i].last_heard_ms != UINT32_MAX)
				cJSON_AddNumberToObject(e, "last_heard_ms", nodes[i].last_heard_ms);
			else
				cJSON_AddNullToObject(e, "last_heard_ms");
			cJSON_AddBoolToObject(e, "bootup_seen", nodes[i].flags & 1);
			cJSON_AddNumberToObject(e, "bootups", nodes[i].bootups);
			cJSON_AddBoolToObject(e, "emcy_active", nodes[i].flags & 2);
			cJSON_AddNumberToObject(e, "emcy_count", nodes[i].emcy_count);
			cJSON_AddNumberToObject(e, "last_emcy", nodes[i].last_emcy);
			cJSON_AddBoolToObject(e, "duplicate_id", nodes[i].flags & 4);
			cJSON_AddItemToArray(na, e);
		}
		cJSON_AddItemToArray(arr, o);
		return 0;
	}
	printf("line %u: CAN %s, %" PRIu32 " kbit/s, bus load %" PRIu32 ".%" PRIu32
	       " %%, own node %u %s\n",
	       line, mbx_can_state_to_string(st.can_state), st.bitrate / 1000u,
	       st.bus_load_permille / 10u, st.bus_load_permille % 10u, st.node_id,
	       nmt_text(st.nmt_state));
	printf("  frames: rx %" PRIu64 ", tx %" PRIu64 ", rx dropped %" PRIu64
	       ", tx failed %" PRIu64 ", error frames %" PRIu64 ", bus-off %" PRIu64 "\n",
	       st.rx_frames, st.tx_frames, st.rx_dropped, st.tx_failed, st.err_frames,
	       st.bus_off_count);
	printf("  mailbox: %" PRIu32 " client%s, %" PRIu64 " commands, %" PRIu64
	       " malformed, %" PRIu64 " denied, %" PRIu64 " events sent, %" PRIu64 " dropped\n",
	       ms.clients, ms.clients == 1 ? "" : "s", ms.commands_ok, ms.malformed,
	       ms.access_denied, ms.events_sent, ms.dropped);
	if (ms.late_wakes) /* leases were not judged then: say why clients outlived one */
		printf("  mailbox woke late %" PRIu64 " time%s (a stall): client leases renewed\n",
		       ms.late_wakes, ms.late_wakes == 1 ? "" : "s");
	if (has_gw) {
		printf("  gateway: network %u, %u routed session%s running, %u client%s lent\n",
		       gw.network_id, gw.active, gw.active == 1 ? "" : "s", gw.leases,
		       gw.leases == 1 ? "" : "s");
		ctl_gw_counters_text(&gw, "    ");
	}
	if (n == 0) {
		printf("  nodes: none heard yet\n");
		return 0;
	}
	printf("  %4s  %-16s  %-13s  %-11s  %-7s  %s\n", "node", "NMT state", "heartbeat",
	       "last heard", "boot-up", "EMCY");
	for (int i = 0; i < n; i++) {
		char heard[24] = "never", emcy[40] = "-";
		if (nodes[i].last_heard_ms != UINT32_MAX)
			snprintf(heard, sizeof heard, "%u.%u s ago", nodes[i].last_heard_ms / 1000u,
				 nodes[i].last_heard_ms % 1000u / 100u);
		if (nodes[i].emcy_count)
			snprintf(emcy, sizeof emcy, "%s, last %04Xh (%u)",
				 nodes[i].flags & 2 ? "error active" : "no error",
				 nodes[i].last_emcy, nodes[i].emcy_count);
		printf("  %4u  %-16s  %-13s  %-11s  %-7s  %s\n", nodes[i].node,
		       nmt_text(nodes[i].nmt_state), hb_text(nodes[i].hb), heard,
		       nodes[i].flags & 1 ? "seen" : "-", emcy);
		if (nodes[i].flags & 4)
			printf("        TWO DEVICES on node-ID %u: two answers came to one SDO "
			       "request\n",
			       nodes[i].node);
	}
	return 0;
}

static int run(ctl *c, int argc, char **argv)
{
	const char *pos[MBX_LINES_MAX];
	int n_pos;
	int rc = ctl_parse(c, argc, argv, NULL, pos, MBX_LINES_MAX, &n_pos);
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_status);
	unsigned lines[MBX_LINES_MAX];
	int n_lines = n_pos;
	for (int i = 0; i < n_pos; i++)
		if (ctl_arg_line(c, pos[i], &lines[i]) < 0)
			return CTL_EXIT_USAGE;
	if (n_lines == 0) {
		int n = ctl_count_lines(c);
		if (n < 0)
			return -n;
		for (int i = 0; i < n; i++)
			lines[i] = (unsigned)i;
		n_lines = n;
	}
	int ex = 0;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	cJSON *arr = c->json ? cJSON_CreateArray() : NULL;
	for (int i = 0; i < n_lines; i++) {
		if (i && !c->json)
			printf("\n");
		rc = status_line(c, h, lines[i], arr);
		if (rc) {
			cJSON_Delete(arr);
			return rc;
		}
	}
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddBoolToObject(o, "ok", true);
		cJSON_AddStringToObject(o, "instance", c->instance);
		cJSON_AddItemToObject(o, "lines", arr);
		ctl_json_print(o);
	}
	return 0;
}

const ctl_cmd ctl_cmd_status = {
	.name = "status",
	.synopsis = "  status [LINE...]                         lines, node tables, counters\n",
	.help = "usage: cogwctl status [LINE...]\n"
		"\n"
		"For every line of the daemon (or the lines given): the CAN controller state, the\n"
		"bit rate, the daemon's own node-ID and NMT state, frame counters (received, "
		"sent,\n"
		"dropped on receive, failed to send, error frames, bus-off events) and mailbox\n"
		"counters (clients, commands, malformed, denied, events sent, dropped), the "
		"gateway's\n"
		"traffic through the line (routed SDO, PDO forwarding, EMCY routing). Then the\n"
		"node table: every node the line has heard or supervises, with its NMT state\n"
		"(from its last heartbeat or boot-up), heartbeat supervision (active, LOST, not\n"
		"monitored), whether its boot-up was seen and whether it reported an EMCY error.\n"
		"\n"
		"Examples:\n"
		"  cogwctl status\n"
		"  cogwctl status 0 --json\n",
	.run = run,
};
