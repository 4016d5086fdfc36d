/* SPDX-License-Identifier: MIT */
/*
 * cogwctl node - a slave added to a line's network list, changed or
 * removed without restarting the line (MBX_CMD_MGR_NODE_SET,
 * docs/cogwctl.md "node"). The options are the keys of a "nodes" entry of
 * the configuration (docs/config.md); a DCF/EDS given with --dcf is
 * converted here by the same reader as cogwd's, so the daemon only gets
 * the concise DCF.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "apps/cogwctl/ctl.h"
#include "apps/common/eds.h"
#include "apps/common/node_config.h"
#include "core/manager.h"
#include "core/nmt.h"

/* The option values as given (NULL = not given). */
struct node_args {
	const char *heartbeat, *guard, *retry, *ident[5], *state, *pdo, *dcf;
	bool mandatory, no_boot, keep_alive, keep_op, store;
};

static int arg_u32(ctl *c, const char *s, const char *name, uint64_t max, uint32_t *v)
{
	uint64_t x = 0;
	if (s && ctl_arg_uint(c, s, name, max, &x) < 0)
		return CTL_EXIT_USAGE;
	*v = (uint32_t)x;
	return 0;
}

static int arg_word(ctl *c, const char *s, const char *name, const char *const *words,
		    const uint8_t *values, uint8_t *v)
{
	if (!s)
		return 0;
	for (size_t i = 0; words[i]; i++)
		if (!strcmp(s, words[i])) {
			*v = values[i];
			return 0;
		}
	return ctl_usage_error(c, "%s: '%s' is not one of the documented words", name, s);
}

/* 1F81h:n's flags (CiA 302-2) from the options. */
static uint32_t assignment_of(const struct node_args *a)
{
	return CO_MGR_1F81_SLAVE | (a->no_boot ? 0 : CO_MGR_1F81_BOOT) |
	       (a->mandatory ? CO_MGR_1F81_MANDATORY : 0) |
	       (a->keep_alive ? CO_MGR_1F81_KEEP_ALIVE : 0);
}

/* 1F81h:n and the rest of the fixed part from the options. */
static int fill_request(ctl *c, const struct node_args *a, mbx_mgr_node_set_req *r)
{
	static const char *const ident_names[5] = { "--device-type", "--vendor-id",
						    "--product-code", "--revision", "--serial" };
	static const char *const states[] = { "operational", "pre-operational", "stopped", NULL };
	static const uint8_t state_values[] = { CO_NMT_OPERATIONAL, CO_NMT_PRE_OPERATIONAL,
						CO_NMT_STOPPED };
	static const char *const pdos[] = { "off", "learn", "auto", NULL };
	static const uint8_t pdo_values[] = { 0, 1, 2 };
	uint32_t hb = 0, guard = 0, retry = 0;
	int rc;

	if ((rc = arg_u32(c, a->heartbeat, "--heartbeat-ms", 65535, &hb)) ||
	    (rc = arg_u32(c, a->guard, "--guard-time-ms", 65535, &guard)) ||
	    (rc = arg_u32(c, a->retry, "--retry-factor", 255, &retry)) ||
	    (rc = arg_word(c, a->state, "--state", states, state_values, &r->target_state)) ||
	    (rc = arg_word(c, a->pdo, "--pdo", pdos, pdo_values, &r->pdo)))
		return rc;
	for (int k = 0; k < 5 && !rc; k++)
		rc = arg_u32(c, a->ident[k], ident_names[k], UINT32_MAX, &r->identity[k]);
	if (rc)
		return rc;
	if (hb && guard)
		return ctl_usage_error(c,
				       "--heartbeat-ms and --guard-time-ms: supervise it one way");
	r->heartbeat_ms = (uint16_t)hb;
	r->assignment = assignment_of(a) | retry << 8 | guard << 16;
	r->flags = (uint8_t)((a->keep_op ? MBX_NODE_F_KEEP_OP : 0) |
			     (a->store ? MBX_NODE_F_STORE : 0));
	return 0;
}

/* --dcf FILE: a concise DCF (.cdc, .bin) as it is, a DCF/EDS converted
 * for this node. */
static int load_dcf(ctl *c, const char *file, uint8_t node, uint8_t **buf, size_t *len)
{
	const char *dot = strrchr(file, '.');
	eds_result res = { 0 };
	int rc;

	if (dot && (!strcmp(dot, ".cdc") || !strcmp(dot, ".bin"))) {
		rc = cogw_cdcf_load_file(file, buf, len, res.err, sizeof res.err);
	} else {
		rc = eds_convert_file(file, node, &res);
		*buf = res.cdcf;
		*len = res.len;
	}
	if (!rc)
		return 0;
	free(*buf);
	*buf = NULL;
	fprintf(stderr, "cogwctl %s: %s\n", c->what, rc == -ENOMEM ? "out of memory" : res.err);
	return rc == -EINVAL ? CTL_EXIT_REFUSED : CTL_EXIT_USAGE;
}

static int answer(ctl *c, unsigned line, uint8_t node, const char *op)
{
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddBoolToObject(o, "ok", true);
		cJSON_AddNumberToObject(o, "line", line);
		cJSON_AddNumberToObject(o, "node", node);
		cJSON_AddStringToObject(o, "done", op);
		ctl_json_print(o);
	} else {
		printf("line %u: node %u %s\n", line, node, op);
	}
	return 0;
}

/* "node add|change|remove LINE NODE": the operation and its two numbers. */
static int node_target(ctl *c, const char **pos, int n_pos, mbx_mgr_node_set_req *r, unsigned *line)
{
	static const char *const ops[] = { "add", "change", "remove", NULL };
	static const uint8_t op_values[] = { MBX_NODE_ADD, MBX_NODE_CHANGE, MBX_NODE_REMOVE };
	int rc;

	if (n_pos < 3)
		return ctl_usage_error(c, "expected add|change|remove LINE NODE");
	if ((rc = arg_word(c, pos[0], "operation", ops, op_values, &r->op)))
		return rc;
	if (ctl_arg_line(c, pos[1], line) < 0 || ctl_arg_node(c, pos[2], &r->node) < 0)
		return CTL_EXIT_USAGE;
	return 0;
}

static int run_node(ctl *c, int argc, char **argv)
{
	struct node_args a = { 0 };
	ctl_opt opts[] = {
		{ "--heartbeat-ms", true, &a.heartbeat, NULL },
		{ "--guard-time-ms", true, &a.guard, NULL },
		{ "--retry-factor", true, &a.retry, NULL },
		{ "--device-type", true, &a.ident[0], NULL },
		{ "--vendor-id", true, &a.ident[1], NULL },
		{ "--product-code", true, &a.ident[2], NULL },
		{ "--revision", true, &a.ident[3], NULL },
		{ "--serial", true, &a.ident[4], NULL },
		{ "--state", true, &a.state, NULL },
		{ "--pdo", true, &a.pdo, NULL },
		{ "--dcf", true, &a.dcf, NULL },
		{ "--mandatory", false, NULL, &a.mandatory },
		{ "--no-boot", false, NULL, &a.no_boot },
		{ "--keep-alive", false, NULL, &a.keep_alive },
		{ "--keep-op", false, NULL, &a.keep_op },
		{ "--store", false, NULL, &a.store },
		{ NULL, false, NULL, NULL },
	};
	const char *pos[3];
	mbx_mgr_node_set_req r = { 0 };
	uint8_t *cdcf = NULL;
	size_t cdcf_len = 0;
	unsigned line = 0;
	char ctx[64];
	int n_pos, ex = 0, rc = ctl_parse(c, argc, argv, opts, pos, 3, &n_pos);

	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_node);
	if ((rc = node_target(c, pos, n_pos, &r, &line)))
		return rc;
	if (r.op != MBX_NODE_REMOVE && (rc = fill_request(c, &a, &r)))
		return rc;
	if (r.op != MBX_NODE_REMOVE && a.dcf && (rc = load_dcf(c, a.dcf, r.node, &cdcf, &cdcf_len)))
		return rc;
	cogw *h = ctl_handle(c, &ex);
	if (!h) {
		free(cdcf);
		return ex;
	}
	snprintf(ctx, sizeof ctx, "node %s %u on line %u", pos[0], r.node, line);
	rc = cogw_mgr_node_set(h, line, &r, cdcf, cdcf_len, c->timeout_ms);
	free(cdcf);
	if (rc < 0)
		return ctl_fail(c, rc, 0, ctx);
	return answer(c, line, r.node,
		      r.op == MBX_NODE_ADD      ? "added"
		      : r.op == MBX_NODE_CHANGE ? "changed"
						: "removed");
}

const ctl_cmd ctl_cmd_node = {
	.name = "node",
	.synopsis = "  node add|change|remove LINE NODE [OPTIONS]\n"
		    "                                           a slave added, changed or removed "
		    "at run time\n",
	.help = "usage: cogwctl node add|change LINE NODE [--heartbeat-ms MS | --guard-time-ms MS\n"
		"               [--retry-factor N]] [--mandatory] [--no-boot] [--keep-alive]\n"
		"               [--device-type X] [--vendor-id X] [--product-code X]\n"
		"               [--revision X] [--serial X] [--state operational|"
		"pre-operational|stopped]\n"
		"               [--keep-op] [--pdo off|learn|auto] [--dcf FILE] [--store]\n"
		"       cogwctl node remove LINE NODE\n"
		"\n"
		"Adds NODE to the network list of line LINE's CiA 302-2 manager, changes it or\n"
		"removes it, without restarting the line: 1F84h..1F88h:NODE (expected identity,\n"
		"0 = not checked), 1F22h:NODE (the concise DCF of --dcf: a .cdc/.bin file as it\n"
		"is, a DCF/EDS converted for NODE), the node's 1016h heartbeat consumer entry,\n"
		"then 1F81h:NODE; the node's boot slave process runs at once (follow it with\n"
		"'cogwctl monitor --line LINE --class boot,manager'). 'change' boots it again\n"
		"with the new values; 'remove' withdraws 1F81h:NODE, its 1016h entry and\n"
		"1F22h:NODE: no longer booted, supervised or reported. The options are the\n"
		"keys of a \"nodes\" entry (docs/config.md). A change lasts until the daemon\n"
		"restarts or its own node is reset (docs/config.md \"Nodes at run time\").\n",
	.run = run_node,
};
