/* SPDX-License-Identifier: MIT */
/*
 * cogwctl route: the CiA 302-7 gateway of each line - its network, its
 * routing table 1F2Ch with the counters per network, routed sessions,
 * relayed frames, PDO forwarding and EMCY routing counters, and the routed
 * sessions running now. The counters' printers serve cogwctl status too.
 */
#include <inttypes.h>
#include <string.h>

#include "apps/cogwctl/ctl.h"

static const char *kind_text(uint8_t k)
{
	return k == 1 ? "attached" : k == 2 ? "router" : "none";
}

static void add_u64(cJSON *o, const char *name, uint64_t v)
{
	cJSON_AddNumberToObject(o, name, (double)v);
}

void ctl_gw_counters_json(cJSON *o, const mbx_gw_status *st)
{
	cJSON *s;

	cJSON_AddNumberToObject(o, "network", st->network_id);
	cJSON_AddNumberToObject(o, "active_sessions", st->active);
	cJSON_AddNumberToObject(o, "leases", st->leases);
	s = cJSON_AddObjectToObject(o, "sdo");
	add_u64(s, "sessions", st->sessions);
	add_u64(s, "routed", st->routed);
	add_u64(s, "aborted", st->aborted);
	add_u64(s, "timed_out", st->timed_out);
	add_u64(s, "refused", st->refused);
	add_u64(s, "relayed_frames", st->relayed_frames);
	add_u64(s, "sent_for_other_lines", st->sdo_across);
	s = cJSON_AddObjectToObject(o, "pdo");
	add_u64(s, "published", st->pdo_published);
	add_u64(s, "forwarded", st->pdo_forwarded);
	add_u64(s, "dropped", st->pdo_dropped);
	add_u64(s, "applied", st->pdo_applied);
	add_u64(s, "triggered", st->pdo_triggered);
	add_u64(s, "sent_for_other_lines", st->pdo_fast);
	s = cJSON_AddObjectToObject(o, "emcy");
	add_u64(s, "consumed", st->emcy_consumed);
	add_u64(s, "forwarded", st->emcy_forwarded);
	add_u64(s, "unroutable", st->emcy_unroutable);
	add_u64(s, "dropped", st->emcy_dropped);
	add_u64(s, "sent", st->emcy_sent);
	add_u64(o, "ring_drops", st->ring_drops);
}

void ctl_gw_counters_text(const mbx_gw_status *st, const char *indent)
{
	printf("%sSDO   sessions %" PRIu64 ", routed %" PRIu64 ", aborted %" PRIu64
	       ", timed out %" PRIu64 ", refused %" PRIu64 ", relayed frames %" PRIu64
	       " (sent for other lines %" PRIu64 ")\n",
	       indent, st->sessions, st->routed, st->aborted, st->timed_out, st->refused,
	       st->relayed_frames, st->sdo_across);
	printf("%sPDO   published %" PRIu64 ", forwarded %" PRIu64
	       " (TPDOs sent for other lines %" PRIu64 "), dropped %" PRIu64 ", applied %" PRIu64
	       " (TPDOs triggered %" PRIu64 ")\n",
	       indent, st->pdo_published, st->pdo_forwarded, st->pdo_fast, st->pdo_dropped,
	       st->pdo_applied, st->pdo_triggered);
	printf("%sEMCY  consumed %" PRIu64 ", forwarded %" PRIu64 ", unroutable %" PRIu64
	       ", dropped %" PRIu64 ", sent %" PRIu64 "\n",
	       indent, st->emcy_consumed, st->emcy_forwarded, st->emcy_unroutable, st->emcy_dropped,
	       st->emcy_sent);
}

static cJSON *line_json(unsigned line, const mbx_gw_status *st, const mbx_gw_route *r, size_t n,
			const mbx_gw_session *ss, size_t n_s)
{
	cJSON *o = cJSON_CreateObject();
	cJSON *routes, *sessions;

	cJSON_AddNumberToObject(o, "line", line);
	ctl_gw_counters_json(o, st);
	routes = cJSON_AddArrayToObject(o, "routes");
	for (size_t i = 0; i < n; i++) {
		cJSON *e = cJSON_CreateObject();
		cJSON_AddNumberToObject(e, "network", r[i].net);
		cJSON_AddStringToObject(e, "kind", kind_text(r[i].kind));
		if (r[i].kind) {
			cJSON_AddNumberToObject(e, "line", r[i].line);
			if (r[i].kind == 2)
				cJSON_AddNumberToObject(e, "router", r[i].router);
		}
		add_u64(e, "routed", r[i].routed);
		add_u64(e, "aborted", r[i].aborted);
		add_u64(e, "timed_out", r[i].timed_out);
		add_u64(e, "refused", r[i].refused);
		cJSON_AddItemToArray(routes, e);
	}
	sessions = cJSON_AddArrayToObject(o, "sessions");
	for (size_t i = 0; i < n_s; i++) {
		cJSON *e = cJSON_CreateObject();
		cJSON_AddNumberToObject(e, "channel", ss[i].channel);
		cJSON_AddNumberToObject(e, "network", ss[i].net);
		cJSON_AddNumberToObject(e, "node", ss[i].node);
		if (ss[i].target_line != 0xFF)
			cJSON_AddNumberToObject(e, "target_line", ss[i].target_line);
		else
			cJSON_AddNullToObject(e, "target_line");
		if (ss[i].router)
			cJSON_AddNumberToObject(e, "router", ss[i].router);
		cJSON_AddStringToObject(e, "state", ss[i].state);
		cJSON_AddNumberToObject(e, "age_ms", ss[i].age_ms);
		cJSON_AddNumberToObject(e, "frames", ss[i].frames);
		cJSON_AddItemToArray(sessions, e);
	}
	return o;
}

static void line_text(unsigned line, const mbx_gw_status *st, const mbx_gw_route *r, size_t n,
		      const mbx_gw_session *ss, size_t n_s)
{
	printf("line %u: network %u, %u routed session%s running, %u client%s lent to other "
	       "lines\n",
	       line, st->network_id, st->active, st->active == 1 ? "" : "s", st->leases,
	       st->leases == 1 ? "" : "s");
	ctl_gw_counters_text(st, "  ");
	printf("  network  route                     routed  aborted  timed-out  refused\n");
	for (size_t i = 0; i < n; i++) {
		char how[40];
		if (r[i].kind == 1)
			snprintf(how, sizeof how, "line %u", r[i].line);
		else if (r[i].kind == 2)
			snprintf(how, sizeof how, "line %u, router node %u", r[i].line,
				 r[i].router);
		else
			snprintf(how, sizeof how, "-");
		printf("  %7u  %-24s %7" PRIu64 "  %7" PRIu64 "  %9" PRIu64 "  %7" PRIu64 "\n",
		       r[i].net, how, r[i].routed, r[i].aborted, r[i].timed_out, r[i].refused);
	}
	if (!n_s)
		return;
	printf("  channel  target               via                 state                        "
	       "age      frames\n");
	for (size_t i = 0; i < n_s; i++) {
		char tgt[24], via[24];
		snprintf(tgt, sizeof tgt, "network %u node %u", ss[i].net, ss[i].node);
		if (ss[i].target_line == 0xFF)
			snprintf(via, sizeof via, "-");
		else if (ss[i].router)
			snprintf(via, sizeof via, "line %u, router %u", ss[i].target_line,
				 ss[i].router);
		else
			snprintf(via, sizeof via, "line %u", ss[i].target_line);
		printf("  %7u  %-19s  %-18s  %-27s  %4u.%u s  %6u\n", ss[i].channel, tgt, via,
		       ss[i].state, ss[i].age_ms / 1000u, ss[i].age_ms % 1000u / 100u,
		       ss[i].frames);
	}
}

static void forward_json(cJSON *o, const mbx_dev_forward *f, size_t n)
{
	cJSON *arr = cJSON_AddArrayToObject(o, "forwarded_objects");
	for (size_t i = 0; i < n; i++) {
		cJSON *e = cJSON_CreateObject();
		char obj[16], peer[16], image[8];
		snprintf(obj, sizeof obj, "%04X:%02X", f[i].index, f[i].sub);
		snprintf(peer, sizeof peer, "%04X:%02X", f[i].peer_index, f[i].peer_sub);
		snprintf(image, sizeof image, "%04X", f[i].image);
		cJSON_AddStringToObject(e, "end", f[i].source ? "from" : "to");
		cJSON_AddNumberToObject(e, "node", f[i].node);
		cJSON_AddStringToObject(e, "object", obj);
		cJSON_AddStringToObject(e, "image", image);
		cJSON_AddNumberToObject(e, "peer_line", f[i].peer_line);
		cJSON_AddNumberToObject(e, "peer_node", f[i].peer_node);
		cJSON_AddStringToObject(e, "peer_object", peer);
		cJSON_AddNumberToObject(e, "values", f[i].values);
		if (!f[i].source) {
			cJSON_AddNumberToObject(e, "sent", f[i].sent);
			cJSON_AddNumberToObject(e, "superseded", f[i].superseded);
		}
		cJSON_AddNumberToObject(e, "refused", f[i].refused);
		cJSON_AddItemToArray(arr, e);
	}
}

/* "values" of a source end, "values, sent, superseded" of a target end:
 * what became of each value is in docs/gateway.md. */
static void forward_text(const mbx_dev_forward *f, size_t n)
{
	if (!n)
		return;
	printf("  forwarded device objects (gateway.forward):\n");
	for (size_t i = 0; i < n; i++) {
		if (f[i].source)
			printf("    node %u %04X:%02X -> line %u node %u %04X:%02X via %04X: %u "
			       "values into the image, %u refused\n",
			       f[i].node, f[i].index, f[i].sub, f[i].peer_line, f[i].peer_node,
			       f[i].peer_index, f[i].peer_sub, f[i].image, f[i].values,
			       f[i].refused);
		else
			printf("    line %u node %u %04X:%02X -> node %u %04X:%02X via %04X: %u "
			       "values taken, %u frames sent, %u superseded, %u refused\n",
			       f[i].peer_line, f[i].peer_node, f[i].peer_index, f[i].peer_sub,
			       f[i].node, f[i].index, f[i].sub, f[i].image, f[i].values, f[i].sent,
			       f[i].superseded, f[i].refused);
	}
}

/* One line's gateway: its status, sessions and device object forwards. */
static int route_line(ctl *c, cogw *h, unsigned line, cJSON *arr)
{
	static mbx_gw_route routes[128];
	static mbx_gw_session sessions[255];
	static mbx_dev_forward fwd[64];
	mbx_gw_status st;
	size_t n = 0, n_s = 0, n_f = 0;
	char ctx[48];
	snprintf(ctx, sizeof ctx, "gateway of line %u", line);
	int rc = cogw_gw_status(h, line, &st, routes, 128, &n, sessions, 255, &n_s, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, ctx);
	if (n > 128)
		n = 128;
	if (n_s > 255)
		n_s = 255;
	/* a daemon without the device object layer has none to show */
	if (cogw_dev_forwards(h, line, fwd, 64, &n_f, c->timeout_ms) < 0)
		n_f = 0;
	if (c->json) {
		cJSON *o = line_json(line, &st, routes, n, sessions, n_s);
		forward_json(o, fwd, n_f);
		cJSON_AddItemToArray(arr, o);
	} else {
		line_text(line, &st, routes, n, sessions, n_s);
		forward_text(fwd, n_f);
	}
	return 0;
}

static int run(ctl *c, int argc, char **argv)
{
	return ctl_run_lines(c, argc, argv, &ctl_cmd_route, route_line);
}

const ctl_cmd ctl_cmd_route = {
	.name = "route",
	.synopsis =
		"  route [LINE...]                          gateway: routing tables, counters\n",
	.help = "usage: cogwctl route [LINE...] [--json]\n"
		"\n"
		"The CiA 302-7 gateway of every line (or the lines given): the line's network,\n"
		"routed SDO sessions (taken, routed, aborted, timed out, refused, running now,\n"
		"frames relayed for other lines), PDO forwarding of the B000h process image\n"
		"(published by RPDOs here, forwarded to other lines, of which TPDOs of other\n"
		"lines sent by this line itself, dropped, applied here and TPDOs triggered),\n"
		"EMCY routing (consumed with a 1F2Fh entry, forwarded,\n"
		"unroutable, dropped, sent here), then the routing table 1F2Ch: every network\n"
		"with a route (attached to a line, or through a router node on a line) and its\n"
		"counters, then the routed SDO sessions running now (server channel, target\n"
		"network and node, the line and router it went to, where the transfer stands,\n"
		"age, frames relayed) and how many of the line's SDO clients are lent to\n"
		"sessions of other lines; and the forwarded device objects (gateway.forward)\n"
		"with what became of their values. See docs/gateway.md.\n"
		"\n"
		"Examples:\n"
		"  cogwctl route\n"
		"  cogwctl route 0 --json\n",
	.run = run,
};
