/* SPDX-License-Identifier: MIT */
/*
 * cogwctl program LINE NODE FILE: a manual program update of a node by the
 * line's CiA 302-3 software manager in the daemon (core/swmgr.h): the image
 * goes to the daemon in one MGR_PROGRAM request (chunked), and the daemon
 * runs stop (1F51h:1 = 0), clear (= 3), block download to 1F50h:1, start
 * (= 1) and verify (1F56h:1 against --expect, else 1F55h:NODE). Progress
 * events (MGR_NODE "program" with this request's corr) are printed while
 * it runs; the answer tells the outcome (status I with the step, object
 * and abort on failure).
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
#include <sys/stat.h>
#include <time.h>

#include "apps/cogwctl/ctl.h"
#include "core/manager.h"
#include "core/sdo.h"
#include "core/swmgr.h"

/* The largest image cogwctl reads: the daemon's mailbox.max_transfer can
 * be set up to 256 MiB; the daemon refuses what exceeds its own (TOO_BIG). */
#define PROGRAM_FILE_MAX (256u << 20)

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec / 1e9;
}

/* The image file: a regular file of 1 byte .. PROGRAM_FILE_MAX, read whole. */
static int read_image(ctl *c, const char *path, uint8_t **image, size_t *len)
{
	struct stat st;
	if (stat(path, &st) < 0) {
		fprintf(stderr, "cogwctl program: %s: %s\n", path, strerror(errno));
		return CTL_EXIT_USAGE;
	}
	if (!S_ISREG(st.st_mode))
		return ctl_usage_error(c, "%s: not a regular file", path);
	if (st.st_size < 1 || (uint64_t)st.st_size > PROGRAM_FILE_MAX)
		return ctl_usage_error(c, "%s: an image of 1..%u bytes, not %lld", path,
				       PROGRAM_FILE_MAX, (long long)st.st_size);
	int rc = ctl_read_file(c, path, image, len);
	if (rc)
		return rc;
	if (*len < 1 || *len > PROGRAM_FILE_MAX) { /* changed while read */
		free(*image);
		return ctl_usage_error(c, "%s: an image of 1..%u bytes, not %zu", path,
				       PROGRAM_FILE_MAX, *len);
	}
	return 0;
}

typedef struct prog_run {
	ctl *c;
	cogw *h;
	unsigned line;
	uint8_t node;
	uint64_t corr;
	cJSON *progress; /* --json: the progress events */
	unsigned last_pct;
} prog_run;

static void show_progress(prog_run *r, const mbx_ev_mgr *e, double t0)
{
	unsigned pct = e->expected ? (unsigned)((uint64_t)e->value * 100u / e->expected) : 100u;
	if (r->progress) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddNumberToObject(o, "sent", e->value);
		cJSON_AddNumberToObject(o, "total", e->expected);
		cJSON_AddNumberToObject(o, "seconds", now_s() - t0);
		cJSON_AddItemToArray(r->progress, o);
		return;
	}
	printf("download  %" PRIu32 " of %" PRIu32 " bytes (%u %%)\n", e->value, e->expected, pct);
	fflush(stdout);
	r->last_pct = pct;
}

/* Wait for the answer to our request, showing its progress events. The
 * timeout runs from the last sign of life (a progress event), so a large
 * image needs no guess of its total time. */
static int wait_answer(prog_run *r, mbx_mgr_program_resp *a, double t0)
{
	for (;;) {
		cogw_msg m;
		int rc = cogw_recv(r->h, &m, (int)r->c->timeout_ms);
		if (rc == COGW_E_AGAIN)
			return COGW_E_TIMEOUT;
		if (rc < 0)
			return rc;
		if (m.corr != r->corr) {
			cogw_msg_release(&m);
			continue;
		}
		if (m.kind == MBX_KIND_EVENT && m.code == MBX_EV_MGR_NODE &&
		    m.len == sizeof(mbx_ev_mgr)) {
			mbx_ev_mgr e;
			memcpy(&e, m.data, sizeof e);
			if (e.what == CO_MGR_NODE_PROGRAM && e.node == r->node)
				show_progress(r, &e, t0);
			cogw_msg_release(&m);
			continue;
		}
		if (m.kind != MBX_KIND_RESPONSE) {
			cogw_msg_release(&m);
			continue;
		}
		rc = m.status;
		if (rc == 0 && m.len == sizeof *a)
			memcpy(a, m.data, sizeof *a);
		else if (rc == 0)
			rc = COGW_E_PROTOCOL;
		cogw_msg_release(&m);
		return rc;
	}
}

static int program_failed(prog_run *r, const mbx_mgr_program_resp *a)
{
	char ctx[256];
	const char *step = co_swmgr_state_to_string(a->step);
	if (!a->abort && a->index == CO_SWMGR_IDX_ID)
		snprintf(ctx, sizeof ctx,
			 "node %u on line %u: %s: 1F56:01 = 0x%08" PRIX32 ", expected 0x%08" PRIX32
			 ": status %c (%s)",
			 r->node, r->line, step, a->found, a->expected, a->status,
			 co_mgr_status_to_string(a->status));
	else if (a->index == CO_SWMGR_IDX_CONTROL)
		snprintf(ctx, sizeof ctx,
			 "node %u on line %u: %s (1F51:01 = %u): status %c (%s), %" PRIu32
			 " bytes sent",
			 r->node, r->line, step,
			 a->step == CO_SWMGR_STOP    ? CO_SWMGR_CTL_STOP
			 : a->step == CO_SWMGR_CLEAR ? CO_SWMGR_CTL_CLEAR
						     : CO_SWMGR_CTL_START,
			 a->status, co_mgr_status_to_string(a->status), a->bytes);
	else
		snprintf(ctx, sizeof ctx,
			 "node %u on line %u: %s %04X:%02X: status %c (%s), %" PRIu32 " bytes sent",
			 r->node, r->line, step, a->index, a->sub, a->status,
			 co_mgr_status_to_string(a->status), a->bytes);
	/* an abort is reported with its code and meaning; a wrong
	 * identification is a refusal of its own (no abort code) */
	return ctl_fail(r->c, a->abort ? COGW_E_ABORT : COGW_E_STATE, a->abort, ctx);
}

/* LINE NODE FILE and the options into r and q; the request (q, then the
 * image) into *msg, malloc'ed, of *msg_len bytes. */
static int program_request(prog_run *r, const char **pos, const char *expect,
			   const char *sdo_timeout, uint8_t **msg, size_t *msg_len)
{
	ctl *c = r->c;
	mbx_mgr_program_req q = { 0 };
	uint64_t want = 0;
	uint8_t *image = NULL;
	size_t len = 0;
	int rc;

	if (ctl_arg_line(c, pos[0], &r->line) < 0 || ctl_arg_node(c, pos[1], &r->node) < 0)
		return CTL_EXIT_USAGE;
	if (expect && ctl_arg_uint(c, expect, "--expect", UINT32_MAX, &want) < 0)
		return CTL_EXIT_USAGE;
	if (expect && !want)
		return ctl_usage_error(c, "--expect: a software identification is not 0");
	if (sdo_timeout) {
		uint64_t ms;
		if (ctl_arg_uint(c, sdo_timeout, "--sdo-timeout", MBX_PROGRAM_SDO_TIMEOUT_MAX,
				 &ms) < 0)
			return CTL_EXIT_USAGE;
		q.sdo_timeout_ms = (uint32_t)ms;
	}
	if ((rc = read_image(c, pos[2], &image, &len)))
		return rc;
	q.node = r->node;
	q.expected = (uint32_t)want;
	*msg = malloc(sizeof q + len);
	if (!*msg) {
		free(image);
		fprintf(stderr, "cogwctl program: out of memory for %zu bytes\n", len);
		return CTL_EXIT_REFUSED;
	}
	memcpy(*msg, &q, sizeof q);
	memcpy(*msg + sizeof q, image, len);
	free(image);
	*msg_len = sizeof q + len;
	return 0;
}

/* The request refused or lost (rc < 0), said in the daemon's terms when
 * it was sent. */
static int program_not_done(prog_run *r, int rc, bool sent)
{
	char ctx[128];
	const char *why = !sent                ? ""
			  : rc == COGW_E_BUSY  ? ": the node is booting or being updated already"
			  : rc == COGW_E_STATE ? ": not now (the network is stopped, or no SDO "
						 "request can be queued)"
			  : rc == COGW_E_UNSUPPORTED ? ": the line has no manager"
						     : "";

	snprintf(ctx, sizeof ctx, "program update of node %u on line %u%s", r->node, r->line, why);
	return ctl_fail(r->c, rc, 0, ctx);
}

static void program_done(prog_run *r, const mbx_mgr_program_resp *a, double dt)
{
	if (r->c->json) {
		cJSON *o = cJSON_CreateObject();
		char idtxt[16];
		cJSON_AddBoolToObject(o, "ok", true);
		cJSON_AddNumberToObject(o, "line", r->line);
		cJSON_AddNumberToObject(o, "node", r->node);
		cJSON_AddNumberToObject(o, "size", (double)a->bytes);
		cJSON_AddStringToObject(o, "transfer", sdo_mode_to_string(a->mode));
		snprintf(idtxt, sizeof idtxt, "0x%08" PRIX32, a->found);
		cJSON_AddStringToObject(o, "software_id", idtxt);
		cJSON_AddBoolToObject(o, "verified", a->expected != 0);
		cJSON_AddNumberToObject(o, "seconds", dt);
		cJSON_AddItemToObject(o, "progress", r->progress);
		r->progress = NULL;
		ctl_json_print(o);
	} else {
		printf("node %u on line %u: program updated and running: stop, clear, %" PRIu32
		       " bytes to 1F50:01 by %s transfer (%.1f KiB/s), start, verify%s; "
		       "software id 0x%08" PRIX32 "\n",
		       r->node, r->line, a->bytes, sdo_mode_to_string(a->mode),
		       (double)a->bytes / 1024.0 / (dt > 1e-6 ? dt : 1e-6),
		       a->expected ? "" : " (nothing to compare with)", a->found);
	}
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
	prog_run r = { .c = c };
	mbx_mgr_program_resp a = { 0 };
	uint8_t *msg = NULL;
	size_t len = 0;
	double t0;
	int rc = ctl_parse(c, argc, argv, opts, pos, 4, &n_pos);

	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_program);
	c->what = "program";
	if (n_pos != 3)
		return ctl_usage_error(c, "expected LINE NODE FILE");
	if ((rc = program_request(&r, pos, expect, sdo_timeout, &msg, &len)))
		return rc;
	r.h = ctl_handle(c, &ex);
	if (!r.h) {
		free(msg);
		return ex;
	}
	/* progress events are manager-class events of this line */
	if ((rc = cogw_subscribe(r.h, r.line, MBX_EVC_MANAGER, NULL, 0, c->timeout_ms)) < 0) {
		free(msg);
		return program_not_done(&r, rc, false);
	}
	if (c->json)
		r.progress = cJSON_CreateArray();
	t0 = now_s();
	rc = cogw_send_async(r.h, r.line, MBX_CMD_MGR_PROGRAM, msg, len, &r.corr);
	free(msg);
	if (rc >= 0)
		rc = wait_answer(&r, &a, t0);
	if (rc < 0 || a.status) {
		cJSON_Delete(r.progress);
		return rc < 0 ? program_not_done(&r, rc, true) : program_failed(&r, &a);
	}
	program_done(&r, &a, now_s() - t0);
	return 0;
}

const ctl_cmd ctl_cmd_program = {
	.name = "program",
	.synopsis = "  program LINE NODE FILE [--expect ID]     update a node's program "
		    "(1F50h..1F56h)\n",
	.help = "usage: cogwctl program LINE NODE FILE [--expect ID] [--sdo-timeout MS] [--json]\n"
		"\n"
		"Manual program update of node NODE on line LINE by the line's CiA 302-3 software\n"
		"manager in the daemon (the line needs a manager section). FILE goes to the\n"
		"daemon, which then runs:\n"
		"  stop      1F51h:1 = 0 (stop the program)\n"
		"  clear     1F51h:1 = 3 (clear the program memory)\n"
		"  download  FILE to 1F50h:1 by SDO block transfer, segmented when the device\n"
		"            refuses block (progress shown; the report names the transfer used)\n"
		"  start     1F51h:1 = 1 (the device checks and starts the new program)\n"
		"  verify    read 1F56h:1; it must equal ID (--expect) or else 1F55h:NODE\n"
		"            (not compared when neither is set)\n"
		"\n"
		"  FILE              the program image: a regular file of 1 byte up to the\n"
		"                    daemon's transfer limit (mailbox.max_transfer, 1 MiB)\n"
		"  --expect ID       expected software identification, decimal or 0x hex\n"
		"  --sdo-timeout MS  per-frame SDO timeout on the bus (at most 60000)\n"
		"\n"
		"A failed step is boot status I (program download failed): the step, the object\n"
		"and the SDO abort with its meaning are printed and the exit code is 1 (4 when "
		"the\n"
		"node did not answer). Refused at once (exit 1): the node is booting or being\n"
		"updated already (busy), the line has no manager (unsupported), the file is too\n"
		"large for the daemon (too big). --timeout counts from the last progress event.\n"
		"\n"
		"Example:\n"
		"  cogwctl program 0 1 firmware.bin --expect 0x3C2A91F0\n",
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
