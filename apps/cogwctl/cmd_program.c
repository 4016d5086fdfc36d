/* SPDX-License-Identifier: MIT */
/*
 * cogwctl program LINE NODE FILE: a manual program update of a node, the
 * steps of the CiA 302-3 software manager (core/swmgr.h) composed from the
 * daemon's SDO client commands: read 1F56h:1, stop (1F51h:1 = 0), clear
 * (= 3), block download of FILE to 1F50h:1, start (= 1), read 1F56h:1
 * again and, with --expect, compare it. Each step is reported as it ends.
 *
 * cogwctl configure LINE NODE|all: the CiA 302-2 configuration request,
 * "conf" written to 1F25h:NODE (128 = all) of the daemon's own OD; the
 * manager of that line runs the boot slave process of the node(s) again,
 * with the software check and the configuration download.
 */
#include <errno.h>
#include <inttypes.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "apps/cogwctl/ctl.h"

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec / 1e9;
}

typedef struct prog_run {
	ctl *c;
	cogw *h;
	unsigned line;
	uint8_t node;
	cogw_sdo_opts opts;
	cJSON *steps; /* --json */
} prog_run;

static void step_done(prog_run *r, const char *name, const char *detail, double t0)
{
	double dt = now_s() - t0;
	if (r->steps) {
		cJSON *s = cJSON_CreateObject();
		cJSON_AddStringToObject(s, "step", name);
		cJSON_AddStringToObject(s, "result", detail);
		cJSON_AddNumberToObject(s, "seconds", dt);
		cJSON_AddItemToArray(r->steps, s);
	} else {
		printf("%-9s %s (%.3f s)\n", name, detail, dt);
		fflush(stdout);
	}
}

/* A failed step: status I (program download failed) with the abort. */
static int step_failed(prog_run *r, int rc, uint32_t abort, const char *what)
{
	char ctx[160];
	snprintf(ctx, sizeof ctx, "node %u on line %u: %s: status I (program download failed)",
		 r->node, r->line, what);
	cJSON_Delete(r->steps);
	r->steps = NULL;
	return ctl_fail(r->c, rc, abort, ctx);
}

static int control(prog_run *r, const char *name, uint8_t cmd)
{
	uint32_t abort = 0;
	double t0 = now_s();
	char what[64];
	int rc = cogw_sdo_write_ex(r->h, r->line, r->node, 0x1F51, 1, &r->opts, &cmd, 1,
				   r->c->timeout_ms, &abort);
	if (rc < 0) {
		snprintf(what, sizeof what, "%s (1F51:01 = %u)", name, cmd);
		return step_failed(r, rc, abort, what);
	}
	snprintf(what, sizeof what, "1F51:01 = %u", cmd);
	step_done(r, name, what, t0);
	return 0;
}

static int read_id(prog_run *r, const char *name, uint32_t *id, bool *have)
{
	uint8_t b[8];
	size_t len = 0;
	uint32_t abort = 0;
	double t0 = now_s();
	char detail[64];
	int rc = cogw_sdo_read_ex(r->h, r->line, r->node, 0x1F56, 1, &r->opts, b, sizeof b, &len,
				  r->c->timeout_ms, &abort);
	*have = rc >= 0 && len == 4;
	if (*have) {
		*id = (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 |
		      (uint32_t)b[3] << 24;
		snprintf(detail, sizeof detail, "1F56:01 = 0x%08" PRIX32, *id);
	} else if (rc >= 0) {
		snprintf(detail, sizeof detail, "1F56:01 has %zu bytes, not 4", len);
	} else {
		char ab[96];
		snprintf(detail, sizeof detail, "1F56:01 not read: %s",
			 abort ? ctl_abort_text(abort, ab, sizeof ab) : "no answer");
	}
	step_done(r, name, detail, t0);
	return rc;
}

static int run_program(ctl *c, int argc, char **argv)
{
	const char *pos[4];
	int n_pos, ex = 0;
	const char *expect = NULL, *sdo_timeout = NULL;
	ctl_opt opts[] = {
		{ "--expect", true, &expect, NULL },
		{ "--sdo-timeout", true, &sdo_timeout, NULL },
		{ NULL, false, NULL, NULL },
	};
	prog_run r = { .c = c, .opts = { .mode = 0 } };
	uint64_t want = 0;
	uint32_t id = 0, abort = 0;
	bool have = false;
	uint8_t *image;
	size_t len;
	double t0;
	char detail[96];
	int rc = ctl_parse(c, argc, argv, opts, pos, 4, &n_pos);

	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_program);
	c->what = "program";
	if (n_pos != 3)
		return ctl_usage_error(c, "expected LINE NODE FILE");
	if (ctl_arg_line(c, pos[0], &r.line) < 0 || ctl_arg_node(c, pos[1], &r.node) < 0)
		return CTL_EXIT_USAGE;
	if (expect && ctl_arg_uint(c, expect, "--expect", UINT32_MAX, &want) < 0)
		return CTL_EXIT_USAGE;
	if (sdo_timeout) {
		uint64_t ms;
		if (ctl_arg_uint(c, sdo_timeout, "--sdo-timeout", 600000, &ms) < 0)
			return CTL_EXIT_USAGE;
		r.opts.sdo_timeout_ms = (uint32_t)ms;
	}
	if ((rc = ctl_read_file(c, pos[2], &image, &len)))
		return rc;
	if (len == 0 || len > UINT32_MAX) {
		free(image);
		return ctl_usage_error(c, "%s: an image of 1..4294967295 bytes, not %zu", pos[2],
				       len);
	}
	r.h = ctl_handle(c, &ex);
	if (!r.h) {
		free(image);
		return ex;
	}
	if (c->json)
		r.steps = cJSON_CreateArray();

	(void)read_id(&r, "check", &id, &have); /* informative: the old program */
	if ((rc = control(&r, "stop", 0)) || (rc = control(&r, "clear", 3)))
		goto out;
	t0 = now_s();
	r.opts.mode = 3; /* SDO_MODE_BLOCK */
	rc = cogw_sdo_write_ex(r.h, r.line, r.node, 0x1F50, 1, &r.opts, image, len, c->timeout_ms,
			       &abort);
	r.opts.mode = 0;
	if (rc < 0) {
		rc = step_failed(&r, rc, abort, "download to 1F50:01");
		goto out;
	}
	snprintf(detail, sizeof detail, "%zu bytes to 1F50:01 by block transfer, %.1f KiB/s", len,
		 (double)len / 1024.0 / (now_s() - t0 > 1e-6 ? now_s() - t0 : 1e-6));
	step_done(&r, "download", detail, t0);
	if ((rc = control(&r, "start", 1)))
		goto out;
	if (read_id(&r, "verify", &id, &have) < 0 || !have) {
		rc = step_failed(&r, COGW_E_STATE, 0, "1F56:01 not readable after the start");
		goto out;
	}
	if (expect && id != (uint32_t)want) {
		char what[96];
		snprintf(what, sizeof what, "1F56:01 = 0x%08" PRIX32 ", expected 0x%08" PRIX32, id,
			 (uint32_t)want);
		rc = step_failed(&r, COGW_E_STATE, 0, what);
		goto out;
	}
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		char idtxt[16];
		cJSON_AddBoolToObject(o, "ok", true);
		cJSON_AddNumberToObject(o, "line", r.line);
		cJSON_AddNumberToObject(o, "node", r.node);
		cJSON_AddNumberToObject(o, "size", (double)len);
		snprintf(idtxt, sizeof idtxt, "0x%08" PRIX32, id);
		cJSON_AddStringToObject(o, "software_id", idtxt);
		cJSON_AddItemToObject(o, "steps", r.steps);
		r.steps = NULL;
		ctl_json_print(o);
	} else {
		printf("node %u on line %u: program updated and running, software id 0x%08" PRIX32
		       "\n",
		       r.node, r.line, id);
	}
	rc = 0;
out:
	cJSON_Delete(r.steps);
	free(image);
	return rc;
}

const ctl_cmd ctl_cmd_program = {
	.name = "program",
	.synopsis = "  program LINE NODE FILE [--expect ID]     update a node's program "
		    "(1F50h..1F56h)\n",
	.help = "usage: cogwctl program LINE NODE FILE [--expect ID] [--sdo-timeout MS] [--json]\n"
		"\n"
		"Manual program update of node NODE on line LINE, the CiA 302-3 software "
		"manager's\n"
		"steps done through the daemon's SDO client, each reported as it ends:\n"
		"  check     read the software identification 1F56h:1 (shown; may be absent)\n"
		"  stop      1F51h:1 = 0 (stop the program)\n"
		"  clear     1F51h:1 = 3 (clear the program memory)\n"
		"  download  FILE to 1F50h:1 by SDO block transfer\n"
		"  start     1F51h:1 = 1 (the device checks and starts the new program)\n"
		"  verify    read 1F56h:1 again; with --expect ID it must equal ID\n"
		"\n"
		"  FILE              the program image (any size up to the daemon's transfer "
		"limit,\n"
		"                    1 MiB by default)\n"
		"  --expect ID       expected software identification (as 1F55h:NODE), decimal or\n"
		"                    0x hex\n"
		"  --sdo-timeout MS  per-frame SDO timeout on the bus\n"
		"\n"
		"A failed step is boot status I (program download failed): the step, the object\n"
		"and the SDO abort with its meaning are printed and the exit code is 1 (4 when "
		"the\n"
		"node did not answer). Raise --timeout for large images (the whole download is\n"
		"one exchange with the daemon).\n"
		"\n"
		"Example:\n"
		"  cogwctl --timeout 60000 program 0 1 firmware.bin --expect 0x3C2A91F0\n",
	.run = run_program,
};

static int run_configure(ctl *c, int argc, char **argv)
{
	const char *pos[3];
	int n_pos, ex = 0;
	unsigned line;
	uint8_t node = 0, sub;
	/* "conf", little-endian as CiA 302-2 writes it */
	static const uint8_t sig[4] = { 'c', 'o', 'n', 'f' };
	uint32_t abort = 0;
	char ctx[96];
	int rc = ctl_parse(c, argc, argv, NULL, pos, 3, &n_pos);

	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_configure);
	c->what = "configure";
	if (n_pos != 2)
		return ctl_usage_error(c, "expected LINE NODE|all");
	if (ctl_arg_line(c, pos[0], &line) < 0)
		return CTL_EXIT_USAGE;
	if (strcmp(pos[1], "all") != 0 && ctl_arg_node(c, pos[1], &node) < 0)
		return CTL_EXIT_USAGE;
	sub = node ? node : 128;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	if (node)
		snprintf(ctx, sizeof ctx, "configuration request 1F25:%02X (node %u) on line %u",
			 sub, node, line);
	else
		snprintf(ctx, sizeof ctx, "configuration request 1F25:80 (all nodes) on line %u",
			 line);
	rc = cogw_od_write(h, line, 0x1F25, sub, sig, sizeof sig, c->timeout_ms, &abort);
	if (rc < 0)
		return ctl_fail(c, rc, abort, ctx);
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddBoolToObject(o, "ok", true);
		cJSON_AddNumberToObject(o, "line", line);
		if (node)
			cJSON_AddNumberToObject(o, "node", node);
		else
			cJSON_AddStringToObject(o, "node", "all");
		ctl_json_print(o);
	} else if (node) {
		printf("line %u: node %u is booted and configured again (cogwctl monitor --class "
		       "boot)\n",
		       line, node);
	} else {
		printf("line %u: every assigned node is booted and configured again\n", line);
	}
	return 0;
}

const ctl_cmd ctl_cmd_configure = {
	.name = "configure",
	.synopsis = "  configure LINE NODE|all                  configuration request (1F25h)\n",
	.help = "usage: cogwctl configure LINE NODE|all [--json]\n"
		"\n"
		"The CiA 302-2 configuration request: writes the signature \"conf\" to 1F25h:NODE\n"
		"(1F25h:128 for all) of the daemon's own object dictionary on line LINE. The\n"
		"line's manager then runs the boot slave process of that node (of every assigned\n"
		"node not booting already) again: identity check, software check and update\n"
		"(1F81h bits 5/6), configuration download (1F22h, 1020h check), start. Follow it\n"
		"with 'cogwctl monitor --class boot' or 'cogwctl diag LINE NODE'.\n"
		"\n"
		"Refusals (exit 1): abort 0x08000022 when the node is booting already or the line\n"
		"has no active manager; 0x06020000 when the line has no manager (no 1F25h).\n"
		"\n"
		"Examples:\n"
		"  cogwctl configure 0 5\n"
		"  cogwctl configure 0 all\n",
	.run = run_configure,
};
