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
#include "mailbox/cogw_health.h"

static const char *nmt_text(uint8_t s)
{
	return s == 0xFF ? "unknown" : co_nmt_state_to_string(s);
}

static const char *hb_text(uint8_t hb)
{
	return hb == 1 ? "active" : hb == 2 ? "LOST" : hb == 3 ? "waiting" : "not monitored";
}

/* What one line reports: its status, node table, mailbox counters and,
 * when the daemon runs the gateway, the gateway's traffic through it. */
typedef struct line_report {
	unsigned line;
	mbx_line_status st;
	mbx_node_entry nodes[128];
	int n_nodes;
	mbx_stats_wire ms;
	mbx_gw_status gw;
	bool has_gw;
	mbx_line_health health;
	bool has_health;
} line_report;

static int fetch_line(ctl *c, cogw *h, unsigned line, line_report *r)
{
	char ctx[64];
	snprintf(ctx, sizeof ctx, "status of line %u", line);
	r->line = line;
	int rc = cogw_line_status(h, line, &r->st, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, ctx);
	int n = cogw_node_table(h, line, r->nodes, 128, c->timeout_ms);
	if (n < 0)
		return ctl_fail(c, n, 0, ctx);
	r->n_nodes = n > 128 ? 128 : n;
	rc = cogw_mbx_stats(h, line, &r->ms, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, ctx);
	/* The gateway's traffic through this line (a daemon without the
	 * gateway answers "unknown command": then there is none to show). */
	r->has_gw = cogw_gw_routes(h, line, &r->gw, NULL, 0, NULL, c->timeout_ms) == 0;
	/* an older daemon has no bus health to show */
	r->has_health = cogw_line_health(h, line, &r->health, c->timeout_ms) == 0;
	return 0;
}

static void frame_counters_json(cJSON *cnt, const mbx_line_status *st)
{
	cJSON_AddNumberToObject(cnt, "rx_frames", (double)st->rx_frames);
	cJSON_AddNumberToObject(cnt, "tx_frames", (double)st->tx_frames);
	cJSON_AddNumberToObject(cnt, "rx_dropped", (double)st->rx_dropped);
	cJSON_AddNumberToObject(cnt, "tx_failed", (double)st->tx_failed);
	cJSON_AddNumberToObject(cnt, "error_frames", (double)st->err_frames);
	cJSON_AddNumberToObject(cnt, "bus_off", (double)st->bus_off_count);
}

static void mailbox_counters_json(cJSON *mb, const mbx_stats_wire *ms)
{
	cJSON_AddNumberToObject(mb, "clients", ms->clients);
	cJSON_AddNumberToObject(mb, "commands_ok", (double)ms->commands_ok);
	cJSON_AddNumberToObject(mb, "malformed", (double)ms->malformed);
	cJSON_AddNumberToObject(mb, "access_denied", (double)ms->access_denied);
	cJSON_AddNumberToObject(mb, "events_sent", (double)ms->events_sent);
	cJSON_AddNumberToObject(mb, "dropped", (double)ms->dropped);
	cJSON_AddNumberToObject(mb, "clients_reaped", (double)ms->clients_reaped);
	cJSON_AddNumberToObject(mb, "late_wakes", (double)ms->late_wakes);
	cJSON_AddNumberToObject(mb, "reg_refused", (double)ms->reg_refused);
	cJSON_AddNumberToObject(mb, "reg_unanswered", (double)ms->reg_unanswered);
}

static cJSON *node_json(const mbx_node_entry *nd)
{
	cJSON *e = cJSON_CreateObject();
	cJSON_AddNumberToObject(e, "node", nd->node);
	cJSON_AddStringToObject(e, "nmt_state", nmt_text(nd->nmt_state));
	cJSON_AddStringToObject(e, "heartbeat",
				nd->hb == 1   ? "active"
				: nd->hb == 2 ? "lost"
				: nd->hb == 3 ? "waiting"
					      : "off");
	if (nd->last_heard_ms != UINT32_MAX)
		cJSON_AddNumberToObject(e, "last_heard_ms", nd->last_heard_ms);
	else
		cJSON_AddNullToObject(e, "last_heard_ms");
	cJSON_AddBoolToObject(e, "bootup_seen", nd->flags & 1);
	cJSON_AddNumberToObject(e, "bootups", nd->bootups);
	cJSON_AddBoolToObject(e, "emcy_active", nd->flags & 2);
	cJSON_AddNumberToObject(e, "emcy_count", nd->emcy_count);
	cJSON_AddNumberToObject(e, "last_emcy", nd->last_emcy);
	cJSON_AddBoolToObject(e, "duplicate_id", nd->flags & 4);
	return e;
}

static void status_json(const line_report *r, cJSON *arr)
{
	cJSON *o = cJSON_CreateObject();
	cJSON_AddNumberToObject(o, "line", r->line);
	cJSON_AddStringToObject(o, "can_state", mbx_can_state_to_string(r->st.can_state));
	cJSON_AddNumberToObject(o, "node_id", r->st.node_id);
	cJSON_AddStringToObject(o, "nmt_state", nmt_text(r->st.nmt_state));
	cJSON_AddNumberToObject(o, "bitrate", r->st.bitrate);
	cJSON_AddNumberToObject(o, "bus_load_percent", r->st.bus_load_permille / 10.0);
	frame_counters_json(cJSON_AddObjectToObject(o, "counters"), &r->st);
	mailbox_counters_json(cJSON_AddObjectToObject(o, "mailbox"), &r->ms);
	if (r->has_gw)
		ctl_gw_counters_json(cJSON_AddObjectToObject(o, "gateway"), &r->gw);
	if (r->has_health)
		ctl_health_json(cJSON_AddObjectToObject(o, "health"), &r->health);
	cJSON *na = cJSON_AddArrayToObject(o, "nodes");
	for (int i = 0; i < r->n_nodes; i++)
		cJSON_AddItemToArray(na, node_json(&r->nodes[i]));
	cJSON_AddItemToArray(arr, o);
}

static void line_text(unsigned line, const mbx_line_status *st)
{
	printf("line %u: CAN %s, %" PRIu32 " kbit/s, bus load %" PRIu32 ".%" PRIu32
	       " %%, own node %u %s\n",
	       line, mbx_can_state_to_string(st->can_state), st->bitrate / 1000u,
	       st->bus_load_permille / 10u, st->bus_load_permille % 10u, st->node_id,
	       nmt_text(st->nmt_state));
	printf("  frames: rx %" PRIu64 ", tx %" PRIu64 ", rx dropped %" PRIu64
	       ", tx failed %" PRIu64 ", error frames %" PRIu64 ", bus-off %" PRIu64 "\n",
	       st->rx_frames, st->tx_frames, st->rx_dropped, st->tx_failed, st->err_frames,
	       st->bus_off_count);
}

static void mailbox_text(const mbx_stats_wire *ms)
{
	printf("  mailbox: %" PRIu32 " client%s, %" PRIu64 " commands, %" PRIu64
	       " malformed, %" PRIu64 " denied, %" PRIu64 " events sent, %" PRIu64 " dropped\n",
	       ms->clients, ms->clients == 1 ? "" : "s", ms->commands_ok, ms->malformed,
	       ms->access_denied, ms->events_sent, ms->dropped);
	if (ms->late_wakes) /* leases were not judged then: say why clients outlived one */
		printf("  mailbox woke late %" PRIu64 " time%s (a stall): client leases renewed\n",
		       ms->late_wakes, ms->late_wakes == 1 ? "" : "s");
	if (ms->reg_refused) /* a REGISTER flood shows here, not in "malformed" */
		printf("  mailbox refused %" PRIu64 " registration%s, %" PRIu64
		       " unanswered (sender may not own the queues named)\n",
		       ms->reg_refused, ms->reg_refused == 1 ? "" : "s", ms->reg_unanswered);
}

static void node_text(const mbx_node_entry *nd)
{
	char heard[24] = "never", emcy[40] = "-";
	if (nd->last_heard_ms != UINT32_MAX)
		snprintf(heard, sizeof heard, "%u.%u s ago", nd->last_heard_ms / 1000u,
			 nd->last_heard_ms % 1000u / 100u);
	if (nd->emcy_count)
		snprintf(emcy, sizeof emcy, "%s, last %04Xh (%u)",
			 nd->flags & 2 ? "error active" : "no error", nd->last_emcy,
			 nd->emcy_count);
	printf("  %4u  %-16s  %-13s  %-11s  %-7s  %s\n", nd->node, nmt_text(nd->nmt_state),
	       hb_text(nd->hb), heard, nd->flags & 1 ? "seen" : "-", emcy);
	if (nd->flags & 4)
		printf("        TWO DEVICES on node-ID %u: two answers came to one SDO "
		       "request\n",
		       nd->node);
}

static void status_text(const line_report *r)
{
	line_text(r->line, &r->st);
	if (r->has_health)
		ctl_health_summary_text(&r->health);
	mailbox_text(&r->ms);
	if (r->has_gw) {
		printf("  gateway: network %u, %u routed session%s running, %u client%s lent\n",
		       r->gw.network_id, r->gw.active, r->gw.active == 1 ? "" : "s", r->gw.leases,
		       r->gw.leases == 1 ? "" : "s");
		ctl_gw_counters_text(&r->gw, "    ");
	}
	if (r->n_nodes == 0) {
		printf("  nodes: none heard yet\n");
		return;
	}
	printf("  %4s  %-16s  %-13s  %-11s  %-7s  %s\n", "node", "NMT state", "heartbeat",
	       "last heard", "boot-up", "EMCY");
	for (int i = 0; i < r->n_nodes; i++)
		node_text(&r->nodes[i]);
}

static int status_line(ctl *c, cogw *h, unsigned line, cJSON *arr)
{
	line_report r;
	int rc = fetch_line(c, h, line, &r);
	if (rc)
		return rc;
	if (c->json)
		status_json(&r, arr);
	else
		status_text(&r);
	return 0;
}

static int run(ctl *c, int argc, char **argv)
{
	return ctl_run_lines(c, argc, argv, &ctl_cmd_status, status_line);
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
		"traffic through the line (routed SDO, PDO forwarding, EMCY routing), the bus\n"
		"health (fault episodes running and counted; cogwctl health for the details). "
		"Then the\n"
		"node table: every node the line has heard or supervises, with its NMT state\n"
		"(from its last heartbeat or boot-up), heartbeat supervision (active, LOST, not\n"
		"monitored), whether its boot-up was seen and whether it reported an EMCY error.\n"
		"\n"
		"Examples:\n"
		"  cogwctl status\n"
		"  cogwctl status 0 --json\n",
	.run = run,
};
