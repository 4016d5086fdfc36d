/* SPDX-License-Identifier: MIT */
/*
 * cogwctl manager | boot | diag: the CiA 302-2 manager of a line - its
 * state and node bit lists, booting the network or one node, starting the
 * network, Request NMT, per-node diagnostics with the last EMCYs.
 */
#include <inttypes.h>
#include <string.h>

#include "apps/cogwctl/ctl.h"
#include "core/emcy.h"
#include "core/manager.h"
#include "core/sdo.h"

static void bits_text(const mbx_mgr_bits *b, char *buf, size_t len)
{
	size_t off = 0;
	buf[0] = '\0';
	for (unsigned n = 1; n < 128 && off < len; n++)
		if ((b->w[n / 32] >> (n % 32)) & 1u)
			off += (size_t)snprintf(buf + off, len - off, "%s%u", off ? "," : "", n);
	if (!off)
		snprintf(buf, len, "-");
}

static cJSON *bits_json(const mbx_mgr_bits *b)
{
	cJSON *a = cJSON_CreateArray();
	for (unsigned n = 1; n < 128; n++)
		if ((b->w[n / 32] >> (n % 32)) & 1u)
			cJSON_AddItemToArray(a, cJSON_CreateNumber(n));
	return a;
}

static void flags_text(uint8_t f, char *buf, size_t len)
{
	snprintf(buf, len, "%s%s%s%s%s", f & CO_MGR_F_OPTIONAL_MISSING ? " optional-missing" : "",
		 f & CO_MGR_F_MANDATORY_MISSING ? " mandatory-missing" : "",
		 f & CO_MGR_F_SLAVE_OPERATIONAL ? " slave-operational" : "",
		 f & CO_MGR_F_MANAGER_OPERATIONAL ? " manager-operational" : "", f ? "" : " -");
}

static const struct {
	const char *name;
	size_t off;
} lists[] = {
	{ "assigned", offsetof(mbx_mgr_status, assigned) },
	{ "present", offsetof(mbx_mgr_status, present) },
	{ "booted", offsetof(mbx_mgr_status, booted) },
	{ "operational", offsetof(mbx_mgr_status, operational) },
	{ "stopped", offsetof(mbx_mgr_status, stopped) },
	{ "pre_operational", offsetof(mbx_mgr_status, preop) },
	{ "mismatch", offsetof(mbx_mgr_status, mismatch) },
	{ "errctrl_lost", offsetof(mbx_mgr_status, errctrl_lost) },
	{ "emcy_active", offsetof(mbx_mgr_status, emcy_active) },
};

/* The supervision of the line's own RPDOs (docs/cogwctl.md, diag):
 * counters and the RPDOs with a deadline or length episode open. */
#define RPDO_ROWS_SHOWN 64
typedef struct rpdo_diag {
	mbx_rpdo_status st;
	mbx_rpdo_fault_entry rows[RPDO_ROWS_SHOWN];
	unsigned n; /* RPDOs with an episode open (may exceed the rows) */
} rpdo_diag;

static void rpdo_out(ctl *c, cJSON *o, const rpdo_diag *r)
{
	const mbx_rpdo_status *st = &r->st;
	unsigned shown = r->n < RPDO_ROWS_SHOWN ? r->n : RPDO_ROWS_SHOWN;
	char f[96];
	if (o) {
		cJSON *p = cJSON_AddObjectToObject(o, "rpdo");
		cJSON_AddNumberToObject(p, "rpdos", st->rpdos);
		cJSON_AddNumberToObject(p, "rx", (double)st->rx);
		cJSON_AddNumberToObject(p, "rx_length", (double)st->rx_length);
		cJSON_AddNumberToObject(p, "rx_timeout", (double)st->rx_timeout);
		cJSON_AddNumberToObject(p, "rx_late", (double)st->rx_late);
		cJSON_AddNumberToObject(p, "od_refused", (double)st->od_refused);
		cJSON_AddNumberToObject(p, "timeout_episodes", st->episodes[0]);
		cJSON_AddNumberToObject(p, "short_episodes", st->episodes[1]);
		cJSON_AddNumberToObject(p, "long_episodes", st->episodes[2]);
		cJSON *a = cJSON_AddArrayToObject(p, "faults");
		for (unsigned i = 0; i < shown; i++) {
			cJSON *e = cJSON_CreateObject();
			cJSON_AddNumberToObject(e, "pdo", r->rows[i].pdo);
			cJSON_AddNumberToObject(e, "cob_id", r->rows[i].cob_id);
			cJSON_AddBoolToObject(e, "timeout",
					      r->rows[i].faults & MBX_RPDO_FAULT_TIMEOUT);
			cJSON_AddBoolToObject(e, "short", r->rows[i].faults & MBX_RPDO_FAULT_SHORT);
			cJSON_AddBoolToObject(e, "long", r->rows[i].faults & MBX_RPDO_FAULT_LONG);
			cJSON_AddNumberToObject(e, "mapped_len", r->rows[i].mapped_len);
			cJSON_AddNumberToObject(e, "event_ms", r->rows[i].event_ms);
			cJSON_AddItemToArray(a, e);
		}
		return;
	}
	(void)c;
	printf("  RPDOs            %u, frames used %" PRIu64 ", wrong length %" PRIu64
	       ", deadlines missed %" PRIu64 ", after the SYNC window %" PRIu64
	       ", values refused %" PRIu64 "\n",
	       st->rpdos, st->rx, st->rx_length, st->rx_timeout, st->rx_late, st->od_refused);
	printf("  RPDO episodes    deadline %" PRIu32 ", short %" PRIu32 ", long %" PRIu32
	       "; open now: %u\n",
	       st->episodes[0], st->episodes[1], st->episodes[2], r->n);
	for (unsigned i = 0; i < shown; i++) {
		ctl_rpdo_fault_text(r->rows[i].faults, ", ", true, f, sizeof f);
		printf("    RPDO %u COB-ID %" PRIX32 "h (%u bytes mapped, deadline %u ms): %s\n",
		       r->rows[i].pdo, r->rows[i].cob_id, r->rows[i].mapped_len,
		       r->rows[i].event_ms, f);
	}
}

static void status_out(ctl *c, unsigned line, const mbx_mgr_status *s, const rpdo_diag *r)
{
	char fl[96], b[512];
	flags_text(s->flags, fl, sizeof fl);
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddBoolToObject(o, "ok", true);
		cJSON_AddNumberToObject(o, "line", line);
		cJSON_AddStringToObject(o, "state", co_mgr_state_to_string(s->state));
		cJSON_AddNumberToObject(o, "flags", s->flags);
		for (size_t i = 0; i < sizeof lists / sizeof lists[0]; i++)
			cJSON_AddItemToObject(
				o, lists[i].name,
				bits_json((const mbx_mgr_bits *)((const char *)s + lists[i].off)));
		if (s->first_error_node) {
			cJSON *e = cJSON_AddObjectToObject(o, "first_error");
			cJSON_AddNumberToObject(e, "node", s->first_error_node);
			char st[2] = { s->first_error_status, 0 };
			cJSON_AddStringToObject(e, "status", st);
			cJSON_AddNumberToObject(e, "code", s->first_error_code);
		}
		cJSON *k = cJSON_AddObjectToObject(o, "counters");
		cJSON_AddNumberToObject(k, "network_boots", s->network_boots);
		cJSON_AddNumberToObject(k, "nmt_ignored", s->nmt_ignored);
		cJSON_AddNumberToObject(k, "unexpected", s->unexpected);
		cJSON_AddNumberToObject(k, "duplicates", s->duplicates);
		cJSON_AddNumberToObject(k, "errctrl_events", s->errctrl_events);
		cJSON_AddNumberToObject(k, "keep_op_restarts", s->keep_op_restarts);
		cJSON_AddNumberToObject(k, "node_changes", s->node_changes);
		cJSON_AddNumberToObject(k, "node_changes_refused", s->node_changes_refused);
		if (r)
			rpdo_out(c, o, r);
		ctl_json_print(o);
		return;
	}
	printf("line %u: manager %s, flags%s\n", line, co_mgr_state_to_string(s->state), fl);
	for (size_t i = 0; i < sizeof lists / sizeof lists[0]; i++) {
		bits_text((const mbx_mgr_bits *)((const char *)s + lists[i].off), b, sizeof b);
		printf("  %-16s %s\n", lists[i].name, b);
	}
	if (s->first_error_node)
		printf("  first error      node %u %s%c code 0x%08" PRIX32 "\n",
		       s->first_error_node, s->first_error_status ? "status " : "EMCY",
		       s->first_error_status ? s->first_error_status : ' ', s->first_error_code);
	printf("  counters         network boots %" PRIu32 ", NMT ignored %" PRIu32
	       ", unexpected %" PRIu32 ", duplicates %" PRIu32 ", error control lost %" PRIu32
	       ", KEEP_OP restarts %" PRIu32 ", node changes %" PRIu32 " (refused %" PRIu32 ")\n",
	       s->network_boots, s->nmt_ignored, s->unexpected, s->duplicates, s->errctrl_events,
	       s->keep_op_restarts, s->node_changes, s->node_changes_refused);
	if (r)
		rpdo_out(c, NULL, r);
}

static int req_value(const char *s)
{
	static const struct {
		const char *n;
		int v;
	} t[] = { { "stop", 4 },
		  { "start", 5 },
		  { "reset-node", 6 },
		  { "reset-comm", 7 },
		  { "pre-operational", 127 },
		  { "preop", 127 } };
	for (size_t i = 0; i < sizeof t / sizeof t[0]; i++)
		if (!strcmp(s, t[i].n))
			return t[i].v;
	return -1;
}

static int done(ctl *c, unsigned line, const char *what)
{
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddBoolToObject(o, "ok", true);
		cJSON_AddNumberToObject(o, "line", line);
		cJSON_AddStringToObject(o, "done", what);
		ctl_json_print(o);
	} else {
		printf("line %u: %s\n", line, what);
	}
	return 0;
}

/* "manager LINE start|reset-counters|request NODE|all STATE". */
static int manager_action(ctl *c, cogw *h, unsigned line, const char **pos, int n_pos)
{
	char ctx[64];
	int rc;

	snprintf(ctx, sizeof ctx, "manager of line %u", line);
	if (!strcmp(pos[1], "start") && n_pos == 2) {
		if ((rc = cogw_mgr_start(h, line, c->timeout_ms)) < 0)
			return ctl_fail(c, rc, 0, ctx);
		return done(c, line, "network started");
	}
	if (!strcmp(pos[1], "reset-counters") && n_pos == 2) {
		if ((rc = cogw_mgr_reset_counters(h, line, c->timeout_ms)) < 0)
			return ctl_fail(c, rc, 0, ctx);
		return done(c, line, "counters reset");
	}
	if (!strcmp(pos[1], "request") && n_pos == 4) {
		uint8_t node = 128;
		int v = req_value(pos[3]);
		if (strcmp(pos[2], "all") && ctl_arg_node(c, pos[2], &node) < 0)
			return CTL_EXIT_USAGE;
		if (v < 0)
			return ctl_usage_error(c,
					       "'%s': expected start, stop, pre-operational, "
					       "reset-node or reset-comm",
					       pos[3]);
		if ((rc = cogw_mgr_request_nmt(h, line, node, (uint8_t)v, c->timeout_ms)) < 0)
			return ctl_fail(c, rc, 0, ctx);
		return done(c, line, "requested");
	}
	return ctl_usage_error(c, "unknown manager action '%s' (start, request, reset-counters)",
			       pos[1]);
}

static int run_manager(ctl *c, int argc, char **argv)
{
	const char *pos[4];
	int n_pos, ex = 0, rc = ctl_parse(c, argc, argv, NULL, pos, 4, &n_pos);
	unsigned line;
	char ctx[64];
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_manager);
	if (n_pos < 1)
		return ctl_usage_error(c, "LINE missing");
	if (ctl_arg_line(c, pos[0], &line) < 0)
		return CTL_EXIT_USAGE;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	snprintf(ctx, sizeof ctx, "manager of line %u", line);
	if (n_pos == 1) {
		mbx_mgr_status s;
		if ((rc = cogw_mgr_status(h, line, &s, c->timeout_ms)) < 0)
			return ctl_fail(c, rc, 0, ctx);
		status_out(c, line, &s, NULL);
		return 0;
	}
	return manager_action(c, h, line, pos, n_pos);
}

static int run_boot(ctl *c, int argc, char **argv)
{
	const char *pos[2];
	int n_pos, ex = 0, rc = ctl_parse(c, argc, argv, NULL, pos, 2, &n_pos);
	unsigned line;
	uint8_t node = 0;
	char ctx[64];
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_boot);
	if (n_pos < 1)
		return ctl_usage_error(c, "LINE missing");
	if (ctl_arg_line(c, pos[0], &line) < 0 || (n_pos > 1 && ctl_arg_node(c, pos[1], &node) < 0))
		return CTL_EXIT_USAGE;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	snprintf(ctx, sizeof ctx, "boot on line %u", line);
	if ((rc = cogw_mgr_boot(h, line, node, c->timeout_ms)) < 0)
		return ctl_fail(c, rc, 0, ctx);
	return done(c, line, node ? "node boot started" : "network boot started");
}

static void diag_out(ctl *c, unsigned line, const mbx_mgr_node_diag *d)
{
	char st[2] = { d->status, 0 };
	if (c->json) {
		cJSON *o = cJSON_CreateObject(), *a;
		cJSON_AddBoolToObject(o, "ok", true);
		cJSON_AddNumberToObject(o, "line", line);
		cJSON_AddNumberToObject(o, "node", d->node);
		cJSON_AddNumberToObject(o, "assignment", d->assignment);
		cJSON_AddBoolToObject(o, "booted", d->booted);
		cJSON_AddBoolToObject(o, "booting", d->booting);
		cJSON_AddNumberToObject(o, "nmt_state", d->nmt_state);
		cJSON_AddStringToObject(o, "step", co_mgr_step_to_string(d->step));
		cJSON_AddStringToObject(o, "status", st);
		cJSON_AddNumberToObject(o, "abort", d->abort);
		cJSON_AddNumberToObject(o, "index", d->index);
		cJSON_AddNumberToObject(o, "sub", d->sub);
		cJSON_AddNumberToObject(o, "value", d->value);
		if (d->status == 'J')
			cJSON_AddNumberToObject(o, "entry", d->value);
		cJSON_AddNumberToObject(o, "boot_count", d->boot_count);
		cJSON_AddNumberToObject(o, "fail_count", d->fail_count);
		cJSON_AddNumberToObject(o, "own_id_frames", d->own_id_frames);
		cJSON_AddNumberToObject(o, "boot_time_ms", (double)d->boot_time_us / 1000.0);
		a = cJSON_AddArrayToObject(o, "emcy");
		for (unsigned i = 0; i < d->n_emcy && i < MBX_MGR_EMCY_MAX; i++) {
			cJSON *e = cJSON_CreateObject();
			cJSON_AddNumberToObject(e, "ts_us", (double)d->emcy[i].time_us);
			cJSON_AddNumberToObject(e, "code", d->emcy[i].code);
			cJSON_AddNumberToObject(e, "register", d->emcy[i].reg);
			cJSON_AddItemToArray(a, e);
		}
		ctl_json_print(o);
		return;
	}
	printf("line %u node %u: %s%s, 1F81h %08" PRIX32 ", NMT state %u\n", line, d->node,
	       d->booted ? "booted" : "not booted", d->booting ? " (booting)" : "", d->assignment,
	       d->nmt_state);
	printf("  boots %" PRIu32 " (last took %.1f ms), failed attempts %" PRIu32 "\n",
	       d->boot_count, (double)d->boot_time_us / 1000.0, d->fail_count);
	if (d->own_id_frames) /* only for the line's own node-ID */
		printf("  frames of another device on our node-ID (EMCY, SDO answer, malformed "
		       "heartbeat): %" PRIu32 "\n",
		       d->own_id_frames);
	if (d->status == 'J') /* value: the concise DCF entry refused */
		printf("  last failure: status J (%s) at %s %04X:%02X, entry %" PRIu32
		       ", abort 0x%08" PRIX32 " (%s)\n",
		       co_mgr_status_to_string(d->status), co_mgr_step_to_string(d->step), d->index,
		       d->sub, d->value, d->abort,
		       d->abort ? sdo_abort_to_string(d->abort) : "none");
	else if (d->status)
		printf("  last failure: status %c (%s) at %s %04X:%02X, abort 0x%08" PRIX32
		       " (%s), value 0x%08" PRIX32 "\n",
		       d->status, co_mgr_status_to_string(d->status),
		       co_mgr_step_to_string(d->step), d->index, d->sub, d->abort,
		       d->abort ? sdo_abort_to_string(d->abort) : "none", d->value);
	for (unsigned i = 0; i < d->n_emcy && i < MBX_MGR_EMCY_MAX; i++)
		printf("  EMCY %04X (%s) register %02X at %.3f s\n", d->emcy[i].code,
		       d->emcy[i].code ? co_emcy_code_to_string(d->emcy[i].code) : "error reset",
		       d->emcy[i].reg, (double)d->emcy[i].time_us / 1e6);
}

static int run_diag(ctl *c, int argc, char **argv)
{
	const char *pos[2];
	int n_pos, ex = 0, rc = ctl_parse(c, argc, argv, NULL, pos, 2, &n_pos);
	unsigned line;
	uint8_t node = 0;
	char ctx[64];
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_diag);
	if (n_pos < 1)
		return ctl_usage_error(c, "LINE missing");
	if (ctl_arg_line(c, pos[0], &line) < 0 || (n_pos > 1 && ctl_arg_node(c, pos[1], &node) < 0))
		return CTL_EXIT_USAGE;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	snprintf(ctx, sizeof ctx, "diagnostics of line %u", line);
	if (!node) {
		mbx_mgr_status s;
		rpdo_diag r;
		if ((rc = cogw_rpdo_status(h, line, &r.st, r.rows, RPDO_ROWS_SHOWN,
					   c->timeout_ms)) < 0)
			return ctl_fail(c, rc, 0, ctx);
		r.n = (unsigned)rc;
		if ((rc = cogw_mgr_status(h, line, &s, c->timeout_ms)) == COGW_E_UNSUPPORTED) {
			/* a line without a manager still supervises its RPDOs */
			cJSON *o = c->json ? cJSON_CreateObject() : NULL;
			if (o) {
				cJSON_AddBoolToObject(o, "ok", true);
				cJSON_AddNumberToObject(o, "line", line);
				cJSON_AddBoolToObject(o, "manager", false);
			} else {
				printf("line %u: no manager\n", line);
			}
			rpdo_out(c, o, &r);
			if (o)
				ctl_json_print(o);
			return 0;
		}
		if (rc < 0)
			return ctl_fail(c, rc, 0, ctx);
		status_out(c, line, &s, &r);
		return 0;
	}
	mbx_mgr_node_diag d;
	if ((rc = cogw_mgr_node_diag(h, line, node, &d, c->timeout_ms)) < 0)
		return ctl_fail(c, rc, 0, ctx);
	diag_out(c, line, &d);
	return 0;
}

const ctl_cmd ctl_cmd_manager = {
	.name = "manager",
	.synopsis =
		"  manager LINE [start|request NODE|all CMD|reset-counters]  CiA 302-2 manager\n",
	.help = "usage: cogwctl manager LINE [--json]\n"
		"       cogwctl manager LINE start\n"
		"       cogwctl manager LINE request NODE|all "
		"start|stop|pre-operational|reset-node|reset-comm\n"
		"       cogwctl manager LINE reset-counters\n"
		"\n"
		"The CiA 302-2 manager of line LINE: its state (resetting, booting, "
		"wait-mandatory,\n"
		"booted, operational, stopped, pre-operational, fatal), flags, the node bit "
		"lists,\n"
		"the first error and the counters. 'start' starts the network when 1F80h leaves\n"
		"that to the application; 'request' is Request NMT (1F82h); 'reset-counters'\n"
		"zeroes counters, EMCY histories and the first error. See docs/cogwctl.md.\n",
	.run = run_manager,
};

const ctl_cmd ctl_cmd_boot = {
	.name = "boot",
	.synopsis =
		"  boot LINE [NODE]                         boot the network or one node again\n",
	.help = "usage: cogwctl boot LINE [NODE] [--json]\n"
		"\n"
		"Runs the network boot of line LINE again (reset communication, boot every\n"
		"assigned node), or the boot slave process of NODE. Follow it with\n"
		"'cogwctl monitor --line LINE --class boot,manager'.\n",
	.run = run_boot,
};

const ctl_cmd ctl_cmd_diag = {
	.name = "diag",
	.synopsis =
		"  diag LINE [NODE]                         manager and RPDO diagnostics, EMCYs\n",
	.help = "usage: cogwctl diag LINE [NODE] [--json]\n"
		"\n"
		"Without NODE: the line's bit lists, first error and counters (as 'manager'),\n"
		"and the supervision of the daemon's own RPDOs on that line: frame counters,\n"
		"deadline and length episodes, and the RPDOs with one open now (also on a\n"
		"line without a manager).\n"
		"With NODE: its last boot status letter with abort code and index:sub, boot\n"
		"count and time, failed attempts, and its last 8 EMCYs with timestamps.\n",
	.run = run_diag,
};
