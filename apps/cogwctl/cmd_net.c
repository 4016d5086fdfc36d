/* SPDX-License-Identifier: MIT */
/*
 * cogwctl nmt, pdo, emcy and lss: network services the daemon carries out
 * on a line as the manager (NMT master, LSS master) or as a node (PDO
 * image, EMCY producer).
 */
#include <ctype.h>
#include <inttypes.h>
#include <stdlib.h>
#include <string.h>

#include "apps/cogwctl/ctl.h"
#include "core/lss.h"
#include "core/nmt.h"

static cJSON *json_ok(unsigned line)
{
	cJSON *o = cJSON_CreateObject();
	cJSON_AddBoolToObject(o, "ok", true);
	cJSON_AddNumberToObject(o, "line", line);
	return o;
}

/* 16-bit hex argument (EMCY error code): "1000", "0x1000", "1000h". */
static int arg_hex16(ctl *c, const char *s, const char *name, uint16_t *v)
{
	char buf[8];
	size_t n = strlen(s);
	const char *p = s;
	if (n >= 2 && p[0] == '0' && (p[1] == 'x' || p[1] == 'X')) {
		p += 2;
		n -= 2;
	}
	if (n && (p[n - 1] == 'h' || p[n - 1] == 'H'))
		n--;
	if (n == 0 || n > 4)
		goto bad;
	memcpy(buf, p, n);
	buf[n] = '\0';
	for (size_t i = 0; i < n; i++)
		if (!isxdigit((unsigned char)buf[i]))
			goto bad;
	*v = (uint16_t)strtoul(buf, NULL, 16);
	return 0;
bad:
	ctl_usage_error(c, "%s '%s': hex 0000..FFFF", name, s);
	return -1;
}

/* ---- nmt ------------------------------------------------------------------ */

static const struct {
	const char *name;
	uint8_t cs;
} nmt_actions[] = {
	{ "start", CO_NMT_CS_START },           { "stop", CO_NMT_CS_STOP },
	{ "preop", CO_NMT_CS_ENTER_PREOP },     { "reset-node", CO_NMT_CS_RESET_NODE },
	{ "reset-comm", CO_NMT_CS_RESET_COMM },
};

static int run_nmt(ctl *c, int argc, char **argv)
{
	const char *pos[4];
	int n_pos;
	int rc = ctl_parse(c, argc, argv, NULL, pos, 4, &n_pos);
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_nmt);
	if (n_pos != 3)
		return ctl_usage_error(c, "expected ACTION LINE NODE|all|self");
	int act = -1;
	for (size_t i = 0; i < sizeof nmt_actions / sizeof nmt_actions[0]; i++)
		if (strcmp(pos[0], nmt_actions[i].name) == 0)
			act = (int)i;
	if (act < 0)
		return ctl_usage_error(
			c, "unknown ACTION '%s' (start, stop, preop, reset-node, reset-comm)",
			pos[0]);
	unsigned line;
	uint8_t node = 0;
	bool self = strcmp(pos[2], "self") == 0;
	if (ctl_arg_line(c, pos[1], &line) < 0)
		return CTL_EXIT_USAGE;
	if (!self && strcmp(pos[2], "all") != 0 && ctl_arg_node(c, pos[2], &node) < 0)
		return CTL_EXIT_USAGE;
	int ex = 0;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	char ctx[80];
	snprintf(ctx, sizeof ctx, "NMT %s to %s on line %u", pos[0], pos[2], line);
	if (self) {
		/* the daemon's own node on that line: its node-ID from the line */
		mbx_line_status st;
		rc = cogw_line_status(h, line, &st, c->timeout_ms);
		if (rc < 0)
			return ctl_fail(c, rc, 0, ctx);
		node = st.node_id;
	}
	rc = cogw_nmt(h, line, nmt_actions[act].cs, node, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, ctx);
	if (c->json) {
		cJSON *o = json_ok(line);
		cJSON_AddStringToObject(o, "nmt", pos[0]);
		cJSON_AddNumberToObject(o, "cs", nmt_actions[act].cs);
		cJSON_AddNumberToObject(o, "node", node);
		ctl_json_print(o);
	} else if (node == 0) {
		printf("line %u: NMT %s sent to all nodes\n", line, pos[0]);
	} else {
		printf("line %u: NMT %s sent to node %u%s\n", line, pos[0], node,
		       self ? " (the daemon itself)" : "");
	}
	return 0;
}

const ctl_cmd ctl_cmd_nmt = {
	.name = "nmt",
	.synopsis = "  nmt start|stop|preop|reset-node|reset-comm LINE NODE|all|self\n"
		    "                                           NMT command to a node, all nodes "
		    "or the daemon\n",
	.help = "usage: cogwctl nmt ACTION LINE NODE|all|self\n"
		"\n"
		"The daemon, as NMT master of line LINE, sends an NMT command (COB-ID 000h):\n"
		"  start       to OPERATIONAL (PDOs run)          cs 01h\n"
		"  stop        to STOPPED                         cs 02h\n"
		"  preop       to PRE-OPERATIONAL                 cs 80h\n"
		"  reset-node  reset application                  cs 81h\n"
		"  reset-comm  reset communication                cs 82h\n"
		"NODE 1..127 addresses one node, 'all' every node (node-ID 0 in the frame),\n"
		"'self' the daemon's own node on that line (applied locally, no frame: the "
		"manager\n"
		"must be OPERATIONAL itself for its RPDOs to deliver process data events).\n"
		"The command succeeds when the frame is queued; watch the effect with\n"
		"'cogwctl status' or 'cogwctl monitor --class nmt,hb'.\n"
		"\n"
		"Examples:\n"
		"  cogwctl nmt start 0 1\n"
		"  cogwctl nmt start 0 self\n"
		"  cogwctl nmt reset-comm 1 all\n",
	.run = run_nmt,
};

/* ---- pdo ------------------------------------------------------------------- */

/* "pdo request LINE TPDO". */
static int pdo_request(ctl *c, int n_pos, const char **pos)
{
	unsigned line;
	uint64_t nr;
	int ex = 0, rc;
	cogw *h;
	char ctx[80];

	c->what = "pdo request";
	if (n_pos != 3)
		return ctl_usage_error(c, "expected LINE TPDO");
	if (ctl_arg_line(c, pos[1], &line) < 0 || ctl_arg_uint(c, pos[2], "TPDO", 512, &nr) < 0)
		return CTL_EXIT_USAGE;
	if (nr == 0)
		return ctl_usage_error(c, "TPDO numbers are 1..512");
	if (!(h = ctl_handle(c, &ex)))
		return ex;
	snprintf(ctx, sizeof ctx, "TPDO %u request on line %u", (unsigned)nr, line);
	rc = cogw_pdo_request(h, line, (uint16_t)nr, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, ctx);
	if (c->json) {
		cJSON *o = json_ok(line);
		cJSON_AddNumberToObject(o, "tpdo", (double)nr);
		ctl_json_print(o);
	} else {
		printf("line %u: TPDO %u sent\n", line, (unsigned)nr);
	}
	return 0;
}

/* The object a "pdo read" or "pdo write" names. */
struct pdo_target {
	unsigned line;
	uint16_t index;
	uint8_t sub;
	const ctl_type *t; /* NULL: none given (read) */
	char ctx[80];      /* for messages */
};

static int pdo_write(ctl *c, const struct pdo_target *x, const char *value, bool trigger)
{
	uint8_t *data;
	size_t len;
	int ex = 0;
	cogw *h;
	int rc = ctl_value_encode(c, x->t, value, &data, &len);

	if (rc)
		return rc;
	if (!(h = ctl_handle(c, &ex))) {
		free(data);
		return ex;
	}
	rc = cogw_pdo_write(h, x->line, x->index, x->sub, data, len, trigger, c->timeout_ms);
	free(data);
	if (rc < 0)
		return ctl_fail(c, rc, 0, x->ctx);
	if (c->json) {
		cJSON *o = json_ok(x->line);
		cJSON_AddNumberToObject(o, "index", x->index);
		cJSON_AddNumberToObject(o, "sub", x->sub);
		cJSON_AddBoolToObject(o, "trigger", trigger);
		ctl_json_print(o);
	} else {
		printf("%04X:%02X <- %s%s: ok\n", x->index, x->sub, value,
		       trigger ? " (TPDOs mapping it sent)" : "");
	}
	return 0;
}

static int pdo_read(ctl *c, const struct pdo_target *x)
{
	uint8_t buf[8];
	size_t len = 0;
	int ex = 0, rc;
	cogw *h;

	if (!(h = ctl_handle(c, &ex)))
		return ex;
	rc = cogw_pdo_read(h, x->line, x->index, x->sub, buf, sizeof buf, &len, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, x->ctx);
	if (x->t && len != x->t->size) {
		fprintf(stderr, "cogwctl: %s: %zu bytes, %s needs %u\n", x->ctx, len, x->t->name,
			x->t->size);
		return CTL_EXIT_REFUSED;
	}
	if (c->json) {
		cJSON *o = json_ok(x->line);
		cJSON_AddNumberToObject(o, "index", x->index);
		cJSON_AddNumberToObject(o, "sub", x->sub);
		cJSON_AddNumberToObject(o, "size", (double)len);
		ctl_value_json(o, x->t, buf, len);
		ctl_json_print(o);
	} else {
		char *text = ctl_value_text(x->t, buf, len);
		printf("%04X:%02X = %s\n", x->index, x->sub, text ? text : "?");
		free(text);
	}
	return 0;
}

/* "pdo read LINE INDEX SUB [TYPE]" and "pdo write LINE INDEX SUB TYPE VALUE". */
static int pdo_access(ctl *c, int n_pos, const char **pos, bool trigger)
{
	bool write = strcmp(pos[0], "write") == 0;
	struct pdo_target x = { 0 };

	if (!write && strcmp(pos[0], "read") != 0)
		return ctl_usage_error(c, "unknown action '%s' (map, request, read, write)",
				       pos[0]);
	c->what = write ? "pdo write" : "pdo read";
	if (write ? n_pos != 6 : (n_pos < 4 || n_pos > 5))
		return ctl_usage_error(c, write ? "expected LINE INDEX SUB TYPE VALUE"
						: "expected LINE INDEX SUB [TYPE]");
	if (ctl_arg_line(c, pos[1], &x.line) < 0 || ctl_arg_index(c, pos[2], &x.index) < 0 ||
	    ctl_arg_sub(c, pos[3], &x.sub) < 0)
		return CTL_EXIT_USAGE;
	if (n_pos >= 5 && !(x.t = ctl_type_find(pos[4])))
		return ctl_usage_error(c, "unknown TYPE '%s'; types: %s", pos[4], ctl_type_names());
	if (x.t && (x.t->size == 0 || x.t->size > 8) && write)
		return ctl_usage_error(c, "process data values are 1..8 bytes: use a numeric type");
	if (!write && trigger)
		return ctl_usage_error(c, "--trigger is for write");
	snprintf(x.ctx, sizeof x.ctx, "process data %s %04X:%02X on line %u",
		 write ? "write" : "read", x.index, x.sub, x.line);
	return write ? pdo_write(c, &x, pos[5], trigger) : pdo_read(c, &x);
}

static int run_pdo(ctl *c, int argc, char **argv)
{
	const char *pos[8];
	int n_pos;
	bool trigger = false;
	ctl_opt opts[] = { { "--trigger", false, NULL, &trigger }, { NULL, false, NULL, NULL } };
	int rc = ctl_parse(c, argc, argv, opts, pos, 8, &n_pos);
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_pdo);
	if (n_pos < 1)
		return ctl_usage_error(c, "map, request, read or write?");
	if (strcmp(pos[0], "map") == 0)
		return ctl_pdo_map(c, n_pos, pos);
	if (strcmp(pos[0], "request") == 0)
		return pdo_request(c, n_pos, pos);
	return pdo_access(c, n_pos, pos, trigger);
}

const ctl_cmd ctl_cmd_pdo = {
	.name = "pdo",
	.synopsis =
		"  pdo map [LINE [NODE]]                    the slaves' PDO layouts and mirror\n"
		"  pdo request LINE TPDO                    send a TPDO of the daemon now\n"
		"  pdo read|write LINE INDEX SUB [TYPE] [VALUE] [--trigger]\n"
		"                                           the daemon's process data image\n",
	.help = "usage: cogwctl pdo map [LINE [NODE]]\n"
		"       cogwctl pdo request LINE TPDO\n"
		"       cogwctl pdo read LINE INDEX SUB [TYPE]\n"
		"       cogwctl pdo write LINE INDEX SUB TYPE VALUE [--trigger]\n"
		"\n"
		"  map        the PDO layouts the daemon learnt of its slaves (from their "
		"DCF/EDS or\n"
		"             by SDO), with the daemon's PDO mirroring each one, or why none "
		"does\n"
		"             (docs/devices.md)\n"
		"Process data of the daemon's node on line LINE:\n"
		"  request    send TPDO number TPDO (1..512) now (it must be valid, and the "
		"daemon\n"
		"             OPERATIONAL: 'cogwctl nmt start LINE self')\n"
		"  read       the current value of a mapped object (what the last RPDO wrote), "
		"1..8 bytes\n"
		"  write      set an object that TPDOs map; --trigger sends the event-driven "
		"TPDOs\n"
		"             that map it at once (else they go with their timer or SYNC)\n"
		"TYPE and VALUE as for 'sdo' (numeric types only for write).\n"
		"To watch received PDOs as they come: 'cogwctl monitor --class pdo'.\n"
		"\n"
		"Examples:\n"
		"  cogwctl pdo read 0 b000 0 r32\n"
		"  cogwctl pdo write 1 b001 0 u16 1200 --trigger\n"
		"  cogwctl pdo request 1 1\n",
	.run = run_pdo,
};

/* ---- emcy ------------------------------------------------------------------ */

static int run_emcy(ctl *c, int argc, char **argv)
{
	const char *pos[6];
	int n_pos;
	int rc = ctl_parse(c, argc, argv, NULL, pos, 6, &n_pos);
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_emcy);
	if (n_pos < 1 || strcmp(pos[0], "send") != 0)
		return ctl_usage_error(c, "expected 'send LINE CODE [REGISTER [DATA]]'");
	c->what = "emcy send";
	if (n_pos < 3 || n_pos > 5)
		return ctl_usage_error(c, "expected LINE CODE [REGISTER [DATA]]");
	unsigned line;
	uint16_t code;
	uint64_t reg = 0;
	uint8_t msef[5] = { 0 };
	if (ctl_arg_line(c, pos[1], &line) < 0 || arg_hex16(c, pos[2], "CODE", &code) < 0)
		return CTL_EXIT_USAGE;
	if (n_pos >= 4 && ctl_arg_uint(c, pos[3], "REGISTER", 255, &reg) < 0)
		return CTL_EXIT_USAGE;
	if (n_pos == 5) {
		size_t n;
		const char *err;
		if (ctl_parse_hex_bytes(pos[4], msef, sizeof msef, &n, &err) < 0)
			return ctl_usage_error(c, "DATA '%s': %s (at most 5 bytes)", pos[4], err);
	}
	int ex = 0;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	char ctx[64];
	snprintf(ctx, sizeof ctx, "EMCY %04X on line %u", code, line);
	rc = cogw_emcy_send(h, line, code, (uint8_t)reg, msef, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, ctx);
	if (c->json) {
		cJSON *o = json_ok(line);
		cJSON_AddNumberToObject(o, "code", code);
		cJSON_AddNumberToObject(o, "register", (double)reg);
		ctl_json_print(o);
	} else if (code == 0) {
		printf("line %u: EMCY error reset sent\n", line);
	} else {
		printf("line %u: EMCY %04X (register %02X) sent\n", line, code, (unsigned)reg);
	}
	return 0;
}

const ctl_cmd ctl_cmd_emcy = {
	.name = "emcy",
	.synopsis = "  emcy send LINE CODE [REGISTER [DATA]]    the daemon sends an EMCY\n",
	.help = "usage: cogwctl emcy send LINE CODE [REGISTER [DATA]]\n"
		"\n"
		"The daemon's node on line LINE sends an emergency message (COB-ID 80h + its\n"
		"node-ID, from 1014h): CODE is the 16-bit error code in hex (0 = error reset:\n"
		"clears the daemon's error history), REGISTER the error register 1001h bits\n"
		"(0..255, default 0), DATA up to 5 manufacturer-specific bytes in hex.\n"
		"Received EMCYs of other nodes: 'cogwctl monitor --class emcy'.\n"
		"\n"
		"Examples:\n"
		"  cogwctl emcy send 0 8130 0x11\n"
		"  cogwctl emcy send 0 1000 1 \"01 02 03\"\n"
		"  cogwctl emcy send 0 0\n",
	.run = run_emcy,
};

/* ---- lss ------------------------------------------------------------------- */

static int lss_fail(ctl *c, int rc, const mbx_lss_resp *r, uint8_t cs, const char *ctx)
{
	if (rc != COGW_E_LSS)
		return ctl_fail(c, rc, 0, ctx);
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddBoolToObject(o, "ok", false);
		cJSON_AddStringToObject(o, "context", ctx);
		cJSON_AddStringToObject(o, "error", "lss");
		cJSON_AddNumberToObject(o, "lss_error", r->error);
		cJSON_AddNumberToObject(o, "lss_spec_error", r->spec_error);
		cJSON_AddStringToObject(o, "lss_error_text", lss_error_to_string(cs, r->error));
		cJSON_AddNumberToObject(o, "exit", CTL_EXIT_REFUSED);
		ctl_json_print(o);
	} else if (r->error == LSS_EC_SPECIFIC) {
		fprintf(stderr,
			"cogwctl: %s: LSS slave error 255 (implementation specific error %u)\n",
			ctx, r->spec_error);
	} else {
		fprintf(stderr, "cogwctl: %s: LSS slave error %u (%s)\n", ctx, r->error,
			lss_error_to_string(cs, r->error));
	}
	return CTL_EXIT_REFUSED;
}

/* What an LSS action's parser sees: the positionals (ACTION LINE ...)
 * and the set-bit-timing options. */
typedef struct lss_args {
	const char *const *pos;
	int n_pos;
	const char *table, *kbit;
} lss_args;

static int lss_parse_switch(ctl *c, const lss_args *a, mbx_lss_req *q)
{
	if (a->n_pos == 3 && !strcmp(a->pos[2], "config"))
		q->mode = LSS_STATE_CONFIGURATION;
	else if (!(a->n_pos == 3 && !strcmp(a->pos[2], "waiting")))
		return ctl_usage_error(c, "expected 'switch LINE waiting|config'");
	return 0;
}

static int lss_parse_select(ctl *c, const lss_args *a, mbx_lss_req *q)
{
	static const char *const names[4] = { "VENDOR", "PRODUCT", "REVISION", "SERIAL" };
	uint32_t *f[4] = { &q->vendor, &q->product, &q->rev_lo, &q->ser_lo };
	uint64_t v;

	if (a->n_pos != 6)
		return ctl_usage_error(c, "expected 'select LINE VENDOR PRODUCT REVISION SERIAL'");
	for (int i = 0; i < 4; i++) {
		if (ctl_arg_uint(c, a->pos[2 + i], names[i], UINT32_MAX, &v) < 0)
			return CTL_EXIT_USAGE;
		*f[i] = (uint32_t)v;
	}
	q->rev_hi = q->rev_lo;
	q->ser_hi = q->ser_lo;
	return 0;
}

static int lss_parse_set_node_id(ctl *c, const lss_args *a, mbx_lss_req *q)
{
	uint64_t v;

	if (a->n_pos != 3)
		return ctl_usage_error(c, "expected 'set-node-id LINE NODE'");
	if (ctl_arg_uint(c, a->pos[2], "NODE", 255, &v) < 0)
		return CTL_EXIT_USAGE;
	if (v == 0 || (v > 127 && v != 255))
		return ctl_usage_error(c, "NODE: 1..127, or 255 = unconfigured");
	q->node = (uint8_t)v;
	return 0;
}

/* --kbit: the index of that bit rate in CiA table 0 (CiA 305). */
static int lss_parse_kbit(ctl *c, const lss_args *a, mbx_lss_req *q)
{
	uint64_t k;
	int idx = -1;

	if (q->table != LSS_BT_TABLE_CIA || a->n_pos != 2 ||
	    ctl_arg_uint(c, a->kbit, "--kbit", 1000, &k) < 0)
		return ctl_usage_error(c, "expected 'set-bit-timing LINE --kbit "
					  "KBIT' (CiA table 0 only)");
	for (uint8_t i = 0; i <= 8; i++)
		if (lss_bit_rate_kbit(i) == k)
			idx = i;
	if (idx < 0)
		return ctl_usage_error(c, "--kbit %" PRIu64 " is not in the CiA bit timing table",
				       k);
	q->bit_index = (uint8_t)idx;
	return 0;
}

static int lss_parse_set_bit_timing(ctl *c, const lss_args *a, mbx_lss_req *q)
{
	uint64_t v;

	if (a->table) {
		if (ctl_arg_uint(c, a->table, "--table", 255, &v) < 0)
			return CTL_EXIT_USAGE;
		q->table = (uint8_t)v;
	}
	if (a->kbit)
		return lss_parse_kbit(c, a, q);
	if (a->n_pos != 3 || ctl_arg_uint(c, a->pos[2], "INDEX", 255, &v) < 0)
		return ctl_usage_error(c, "expected 'set-bit-timing LINE INDEX "
					  "[--table T]' or '--kbit KBIT'");
	q->bit_index = (uint8_t)v;
	return 0;
}

static int lss_parse_activate(ctl *c, const lss_args *a, mbx_lss_req *q)
{
	uint64_t v;

	if (a->n_pos != 3 || ctl_arg_uint(c, a->pos[2], "DELAY_MS", 65535, &v) < 0)
		return ctl_usage_error(c, "expected 'activate-bit-timing LINE DELAY_MS'");
	q->delay_ms = (uint16_t)v;
	return 0;
}

static int lss_parse_inquire(ctl *c, const lss_args *a, mbx_lss_req *q)
{
	static const char *const what[] = { "vendor", "product", "revision", "serial", "node" };

	q->what = 0;
	for (int i = 0; i < 5 && a->n_pos == 3; i++)
		if (!strcmp(a->pos[2], what[i]))
			q->what = (uint8_t)(LSS_CS_INQUIRE_VENDOR + i);
	if (!q->what)
		return ctl_usage_error(
			c, "expected 'inquire LINE vendor|product|revision|serial|node'");
	return 0;
}

#define LSS_WANT_BY_KBIT (-1) /* set-bit-timing: no INDEX with --kbit */

/* The LSS master's actions (CiA 305): the mailbox command, the command
 * specifier whose error codes apply (0: none), the positionals after
 * LINE, and the parser of those (NULL: none). */
static const struct lss_action {
	const char *name;
	uint16_t cmd;
	uint8_t cs;
	int want;
	int (*parse)(ctl *c, const lss_args *a, mbx_lss_req *q);
} lss_actions[] = {
	{ "switch", MBX_CMD_LSS_SWITCH_GLOBAL, 0, 1, lss_parse_switch },
	{ "select", MBX_CMD_LSS_SWITCH_SELECTIVE, 0, 4, lss_parse_select },
	{ "set-node-id", MBX_CMD_LSS_SET_NODE_ID, LSS_CS_CONFIG_NODE_ID, 1, lss_parse_set_node_id },
	{ "set-bit-timing", MBX_CMD_LSS_SET_BIT_TIMING, LSS_CS_CONFIG_BIT_TIMING, LSS_WANT_BY_KBIT,
	  lss_parse_set_bit_timing },
	{ "activate-bit-timing", MBX_CMD_LSS_ACTIVATE_BIT_TIMING, 0, 1, lss_parse_activate },
	{ "store", MBX_CMD_LSS_STORE, LSS_CS_STORE, 0, NULL },
	{ "inquire", MBX_CMD_LSS_INQUIRE, 0, 1, lss_parse_inquire },
	{ "identify", MBX_CMD_LSS_IDENTIFY_NONCONF, 0, 0, NULL },
	{ "fastscan", MBX_CMD_LSS_FASTSCAN, 0, 0, NULL },
};

static const struct lss_action *lss_action_of(const char *name)
{
	for (size_t i = 0; i < sizeof lss_actions / sizeof lss_actions[0]; i++)
		if (!strcmp(lss_actions[i].name, name))
			return &lss_actions[i];
	return NULL;
}

/* No slave answered (or identify found none): exit 3. */
static int lss_none_found(ctl *c, unsigned line, uint16_t cmd, const char *ctx)
{
	if (c->json) {
		cJSON *o = json_ok(line);
		cJSON_ReplaceItemInObject(o, "ok", cJSON_CreateBool(false));
		cJSON_AddBoolToObject(o, "found", false);
		cJSON_AddNumberToObject(o, "exit", CTL_EXIT_REFUSED);
		ctl_json_print(o);
	} else {
		fprintf(stderr, "cogwctl: %s: no LSS slave answered%s\n", ctx,
			cmd == MBX_CMD_LSS_FASTSCAN || cmd == MBX_CMD_LSS_IDENTIFY_NONCONF
				? " (only unconfigured slaves, node-ID 255, take part)"
				: "");
	}
	return CTL_EXIT_REFUSED;
}

static void lss_print_result(ctl *c, unsigned line, const char *act, const char *inquired,
			     uint16_t cmd, const mbx_lss_resp *r)
{
	cJSON *o = c->json ? json_ok(line) : NULL;
	if (o)
		cJSON_AddStringToObject(o, "lss", act);
	switch (cmd) {
	case MBX_CMD_LSS_FASTSCAN:
		if (o) {
			cJSON_AddBoolToObject(o, "found", true);
			cJSON_AddNumberToObject(o, "vendor", r->id[0]);
			cJSON_AddNumberToObject(o, "product", r->id[1]);
			cJSON_AddNumberToObject(o, "revision", r->id[2]);
			cJSON_AddNumberToObject(o, "serial", r->id[3]);
		} else {
			printf("line %u: found vendor 0x%08" PRIX32 " product 0x%08" PRIX32
			       " revision 0x%08" PRIX32 " serial 0x%08" PRIX32 " (%" PRIu32 ")\n"
			       "  that slave is now in LSS configuration state: 'lss set-node-id "
			       "%u NODE', 'lss store %u'\n",
			       line, r->id[0], r->id[1], r->id[2], r->id[3], r->id[3], line, line);
		}
		break;
	case MBX_CMD_LSS_INQUIRE:
		if (o)
			cJSON_AddNumberToObject(o, "value", r->value);
		else
			printf("line %u: %s = %" PRIu32 " (0x%08" PRIX32 ")\n", line, inquired,
			       r->value, r->value);
		break;
	case MBX_CMD_LSS_IDENTIFY_NONCONF:
		if (o)
			cJSON_AddBoolToObject(o, "found", true);
		else
			printf("line %u: unconfigured LSS slaves are present\n", line);
		break;
	default:
		if (!o)
			printf("line %u: LSS %s: ok\n", line, act);
		break;
	}
	if (o)
		ctl_json_print(o);
}

/* ACTION LINE [ARGS] and the options of "lss": the action, the line and
 * the request. */
static int lss_request(ctl *c, lss_args *a, const struct lss_action **la, unsigned *line,
		       mbx_lss_req *q)
{
	int rc;

	if (a->n_pos < 2)
		return ctl_usage_error(c, "expected ACTION LINE ...");
	const char *act = a->pos[0];
	if (ctl_arg_line(c, a->pos[1], line) < 0)
		return CTL_EXIT_USAGE;
	*la = lss_action_of(act);
	if (!*la)
		return ctl_usage_error(c, "unknown ACTION '%s'", act);
	memset(q, 0, sizeof *q);
	if ((*la)->parse && (rc = (*la)->parse(c, a, q)) != 0)
		return rc;
	int want = (*la)->want == LSS_WANT_BY_KBIT ? (a->kbit ? 0 : 1) : (*la)->want;
	if (a->n_pos != 2 + want)
		return ctl_usage_error(c, "wrong number of arguments for '%s'", act);
	if ((a->table || a->kbit) && (*la)->cmd != MBX_CMD_LSS_SET_BIT_TIMING)
		return ctl_usage_error(c, "--table/--kbit are for set-bit-timing");
	return 0;
}

static int run_lss(ctl *c, int argc, char **argv)
{
	const char *pos[8];
	lss_args a = { .pos = pos };
	ctl_opt opts[] = {
		{ "--table", true, &a.table, NULL },
		{ "--kbit", true, &a.kbit, NULL },
		{ NULL, false, NULL, NULL },
	};
	int rc = ctl_parse(c, argc, argv, opts, pos, 8, &a.n_pos);
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_lss);
	const struct lss_action *la = NULL;
	unsigned line;
	mbx_lss_req q;
	if ((rc = lss_request(c, &a, &la, &line, &q)))
		return rc;
	const char *act = pos[0];

	int ex = 0;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	char ctx[64];
	snprintf(ctx, sizeof ctx, "LSS %s on line %u", act, line);
	mbx_lss_resp r;
	memset(&r, 0, sizeof r);
	rc = cogw_lss(h, line, la->cmd, &q, &r, c->timeout_ms);
	if (rc == COGW_E_NOT_FOUND ||
	    (rc == 0 && la->cmd == MBX_CMD_LSS_IDENTIFY_NONCONF && !r.found))
		return lss_none_found(c, line, la->cmd, ctx);
	if (rc < 0)
		return lss_fail(c, rc, &r, la->cs, ctx);
	lss_print_result(c, line, act, a.n_pos > 2 ? pos[2] : NULL, la->cmd, &r);
	return 0;
}

const ctl_cmd ctl_cmd_lss = {
	.name = "lss",
	.synopsis = "  lss fastscan|identify|switch|select|set-node-id|set-bit-timing|\n"
		    "      activate-bit-timing|store|inquire LINE ...\n"
		    "                                           LSS master (CiA 305)\n",
	.help = "usage: cogwctl lss ACTION LINE [ARGS]\n"
		"\n"
		"The daemon as LSS master (CiA 305) on line LINE:\n"
		"  fastscan LINE                find one unconfigured slave (node-ID 255) by its\n"
		"                               identity (1018h); it is left in configuration "
		"state\n"
		"  identify LINE                are there unconfigured slaves?\n"
		"  switch LINE waiting|config   switch state global (all slaves)\n"
		"  select LINE VENDOR PRODUCT REVISION SERIAL\n"
		"                               switch state selective: that slave to "
		"configuration\n"
		"  set-node-id LINE NODE        configure node-ID (1..127, 255 = unconfigured)\n"
		"  set-bit-timing LINE INDEX [--table T]   configure bit timing (table 0 = CiA)\n"
		"  set-bit-timing LINE --kbit KBIT         the same by bit rate (CiA table)\n"
		"  activate-bit-timing LINE DELAY_MS       all slaves switch after DELAY_MS\n"
		"  store LINE                   store configuration (node-ID, bit timing)\n"
		"  inquire LINE vendor|product|revision|serial|node\n"
		"                               ask the slave in configuration state\n"
		"A slave's error answer is printed with its meaning (exit 1); no answer at all\n"
		"is exit 4 (fastscan/identify finding nobody: exit 1, \"no LSS slave answered\").\n"
		"\n"
		"Example: give the unconfigured slave on line 2 node-ID 5 and keep it:\n"
		"  cogwctl lss fastscan 2\n"
		"  cogwctl lss set-node-id 2 5\n"
		"  cogwctl lss store 2\n"
		"  cogwctl lss switch 2 waiting\n"
		"  cogwctl nmt reset-comm 2 all    (the slave boots with node-ID 5)\n",
	.run = run_lss,
};
