/* SPDX-License-Identifier: MIT */
/*
 * cogwctl scan: which node-IDs of a line answer, with their device type
 * and identity (1000h, 1018h:1..4), and the line's cache of what was read
 * (docs/cogwctl.md "scan").
 */
#include <inttypes.h>
#include <string.h>

#include "apps/cogwctl/ctl.h"
#include "mailbox/cogw_scan.h"

static void node_json(cJSON *arr, const mbx_node_ident *id)
{
	cJSON *o = cJSON_CreateObject();
	char hex[16];
	cJSON_AddNumberToObject(o, "node", id->node);
	cJSON_AddStringToObject(o, "source", mbx_ident_source_to_string(id->source));
	cJSON_AddNumberToObject(o, "nmt_state", id->nmt_state);
	cJSON_AddBoolToObject(o, "identity", id->flags & MBX_IDENT_IDENTITY);
	cJSON_AddBoolToObject(o, "stopped_not_read", id->flags & MBX_IDENT_NOT_ASKED);
	const struct {
		const char *name;
		uint32_t v;
		bool valid;
	} f[] = {
		{ "device_type", id->device_type, id->flags & MBX_IDENT_PRESENT },
		{ "vendor_id", id->vendor_id, id->flags & MBX_IDENT_IDENTITY },
		{ "product_code", id->product_code, id->flags & MBX_IDENT_IDENTITY },
		{ "revision", id->revision, id->flags & MBX_IDENT_IDENTITY },
		{ "serial", id->serial, id->flags & MBX_IDENT_SERIAL },
	};
	for (size_t i = 0; i < sizeof f / sizeof f[0]; i++) {
		snprintf(hex, sizeof hex, "0x%08" PRIX32, f[i].v);
		if (f[i].valid)
			cJSON_AddStringToObject(o, f[i].name, hex);
		else
			cJSON_AddNullToObject(o, f[i].name);
	}
	if (id->abort)
		cJSON_AddNumberToObject(o, "abort", id->abort);
	cJSON_AddNumberToObject(o, "age_ms", id->age_ms);
	cJSON_AddItemToArray(arr, o);
}

static void node_text(const mbx_node_ident *id)
{
	char buf[80];
	if (id->flags & MBX_IDENT_NOT_ASKED) {
		printf("  %3u  %-9s  (stopped: not read)\n", id->node,
		       mbx_ident_source_to_string(id->source));
		return;
	}
	printf("  %3u  %-9s  %08" PRIX32, id->node, mbx_ident_source_to_string(id->source),
	       id->device_type);
	if (id->flags & MBX_IDENT_IDENTITY)
		printf("  %08" PRIX32 "  %08" PRIX32 "  %08" PRIX32, id->vendor_id,
		       id->product_code, id->revision);
	else
		printf("  (1018h: %s)", ctl_abort_text(id->abort, buf, sizeof buf));
	if (id->flags & MBX_IDENT_SERIAL)
		printf("  %08" PRIX32, id->serial);
	printf("  %" PRIu32 ".%" PRIu32 " s ago\n", id->age_ms / 1000u, id->age_ms % 1000u / 100u);
}

static void result_print(ctl *c, unsigned line, const cogw_scan_result *r, bool cache)
{
	const mbx_scan_resp *f = &r->figures;
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddBoolToObject(o, "ok", true);
		cJSON_AddNumberToObject(o, "line", line);
		cJSON_AddNumberToObject(o, "first", f->first);
		cJSON_AddNumberToObject(o, "last", f->last);
		cJSON_AddNumberToObject(o, "parallel", f->parallel);
		cJSON_AddNumberToObject(o, "timeout_ms", f->timeout_ms);
		cJSON_AddNumberToObject(o, "duration_ms", f->duration_ms);
		cJSON_AddNumberToObject(o, "bound_ms", f->bound_ms);
		cJSON_AddNumberToObject(o, "requests", f->requests);
		if (cache && f->age_ms != UINT32_MAX)
			cJSON_AddNumberToObject(o, "scan_ms_ago", f->age_ms);
		cJSON *arr = cJSON_AddArrayToObject(o, "nodes");
		for (unsigned i = 0; i < r->n_nodes; i++)
			node_json(arr, &r->nodes[i]);
		ctl_json_print(o);
		return;
	}
	if (!f->first)
		printf("line %u: no scan yet\n", line);
	else
		printf("line %u: %s nodes %u..%u: %" PRIu32 " ms (bound %" PRIu32
		       " ms), %u at once, %u ms per frame, %" PRIu32 " SDO requests\n",
		       line, cache ? "last scan of" : "scanned", f->first, f->last, f->duration_ms,
		       f->bound_ms, f->parallel, f->timeout_ms, f->requests);
	printf("  %u node%s%s\n", r->n_nodes, r->n_nodes == 1 ? "" : "s",
	       cache ? " known (scans and unknown nodes heard)" : " answered");
	if (r->n_nodes)
		printf("  node source     1000h     vendor    product   revision  serial\n");
	for (unsigned i = 0; i < r->n_nodes; i++)
		node_text(&r->nodes[i]);
}

static int scan_args(ctl *c, const char *range, const char *timeout, const char *parallel,
		     uint8_t nodes[2], uint64_t *t, uint64_t *p)
{
	uint8_t first = 1, last = 127;
	if (range) {
		char a[8] = "", b[8] = "";
		const char *dash = strchr(range, '-');
		size_t la = dash ? (size_t)(dash - range) : strlen(range);
		if (la >= sizeof a || (dash && strlen(dash + 1) >= sizeof b))
			return ctl_usage_error(c, "--nodes: expected FIRST-LAST, got \"%s\"",
					       range);
		memcpy(a, range, la);
		snprintf(b, sizeof b, "%s", dash ? dash + 1 : a);
		if (ctl_arg_node(c, a, &first) < 0 || ctl_arg_node(c, b, &last) < 0)
			return CTL_EXIT_USAGE;
		if (first > last)
			return ctl_usage_error(c, "--nodes: %u comes after %u", first, last);
	}
	nodes[0] = first;
	nodes[1] = last;
	*t = *p = 0;
	if (timeout && ctl_arg_uint(c, timeout, "--timeout-ms", MBX_SCAN_TIMEOUT_MAX_MS, t) < 0)
		return CTL_EXIT_USAGE;
	if (parallel && ctl_arg_uint(c, parallel, "--parallel", 128, p) < 0)
		return CTL_EXIT_USAGE;
	return 0;
}

static int run(ctl *c, int argc, char **argv)
{
	const char *pos[2], *range = NULL, *timeout = NULL, *parallel = NULL;
	bool cache = false;
	const ctl_opt opts[] = { { "--nodes", true, &range, NULL },
				 { "--timeout-ms", true, &timeout, NULL },
				 { "--parallel", true, &parallel, NULL },
				 { "--cache", false, NULL, &cache },
				 { NULL, false, NULL, NULL } };
	int n_pos, ex = 0, rc = ctl_parse(c, argc, argv, opts, pos, 2, &n_pos);
	unsigned line;
	uint8_t nodes[2] = { 1, 127 };
	uint64_t t = 0, p = 0;
	char ctx[48];
	cogw_scan_result r;
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_scan);
	if (n_pos != 1)
		return ctl_usage_error(c, "expected LINE");
	if (ctl_arg_line(c, pos[0], &line) < 0 ||
	    (rc = scan_args(c, range, timeout, parallel, nodes, &t, &p)))
		return rc ? rc : CTL_EXIT_USAGE;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	snprintf(ctx, sizeof ctx, "%s of line %u", cache ? "scan cache" : "scan", line);
	rc = cache ? cogw_node_scan_cache(h, line, &r)
		   : cogw_node_scan(h, line, nodes[0], nodes[1], (unsigned)t, (unsigned)p, 0, &r);
	if (rc < 0)
		return ctl_fail(c, rc, 0, ctx);
	result_print(c, line, &r, cache);
	return 0;
}

const ctl_cmd ctl_cmd_scan = {
	.name = "scan",
	.synopsis =
		"  scan LINE [--nodes A-B] [--cache]       node-IDs that answer, their identity\n",
	.help = "usage: cogwctl scan LINE [--nodes FIRST-LAST] [--timeout-ms MS] [--parallel N]\n"
		"       cogwctl scan LINE --cache\n"
		"\n"
		"Asks every node-ID of LINE (1-127, or FIRST-LAST) for its device type (1000h)\n"
		"and identity (1018h:1..4, serial optional) through the line's SDO client pool,\n"
		"N nodes at once (default: every SDO client channel of the line), MS per SDO\n"
		"frame (default: the line's unknown_nodes.sdo_timeout_ms, 100), and prints the\n"
		"nodes that answered. A node that does not answer 1000h within MS is absent; a\n"
		"node in STOPPED does not answer SDO (CiA 301) and is not found. The scan ends\n"
		"within ceil(nodes / N) x 5 x MS when no other transfer uses the pool (absent\n"
		"nodes cost one MS each, N at a time). It needs write rights (it keeps the\n"
		"line's SDO clients busy); one scan at a time per line.\n"
		"\n"
		"--cache prints what the line read so far (scans, and unknown nodes it heard,\n"
		"docs/config.md \"unknown_nodes\") without asking the bus; read rights suffice.\n"
		"\n"
		"Examples:\n"
		"  cogwctl scan 0\n"
		"  cogwctl scan 0 --nodes 1-32 --timeout-ms 50 --json\n"
		"  cogwctl scan 0 --cache\n",
	.run = run,
};
