/* SPDX-License-Identifier: MIT */
/*
 * cogwctl sdo read|write (the daemon is the SDO client on a line) and
 * od read|write (the daemon's own object dictionary of a line). Both share
 * the value handling: a TYPE turns text into wire bytes and back; without
 * a TYPE a read shows the bytes and a guess.
 */
#include <errno.h>
#include <inttypes.h>
#include <stdlib.h>
#include <string.h>

#include "apps/cogwctl/ctl.h"
#include "apps/common/node_config.h"
#include "core/cdcf.h"

/* Largest answer we prepare for at first; a bigger one (the daemon's
 * max_transfer can be raised) is read again with the size it announced.
 * The first buffer is static (.bss): its pages exist only once touched, so
 * a read of a few bytes pays neither the mmap/munmap that malloc makes for
 * a block this large nor more than one page (docs/fastpath.md, "One-shot
 * `cogwctl`"). */
#define READ_CAP_FIRST (1024u * 1024u)
static uint8_t first_answer[READ_CAP_FIRST];

typedef struct obj_args {
	bool remote; /* sdo (true) or od (false) */
	unsigned line;
	uint8_t node;
	uint16_t net; /* --net: routed through the daemon's gateway (0 = no) */
	uint16_t index;
	uint8_t sub;
	const ctl_type *type;
	cogw_sdo_opts opts;
	const char *out_path;
} obj_args;

static void context(const obj_args *a, bool write, char *buf, size_t len)
{
	if (a->remote && a->net)
		snprintf(buf, len, "SDO %s %04X:%02X node %u of network %u via line %u",
			 write ? "download" : "upload", a->index, a->sub, a->node, a->net, a->line);
	else if (a->remote)
		snprintf(buf, len, "SDO %s %04X:%02X node %u on line %u",
			 write ? "download" : "upload", a->index, a->sub, a->node, a->line);
	else
		snprintf(buf, len, "local OD %s %04X:%02X on line %u", write ? "write" : "read",
			 a->index, a->sub, a->line);
}

static cJSON *json_head(const obj_args *a)
{
	cJSON *o = cJSON_CreateObject();
	char idx[8];
	cJSON_AddBoolToObject(o, "ok", true);
	cJSON_AddNumberToObject(o, "line", a->line);
	if (a->remote)
		cJSON_AddNumberToObject(o, "node", a->node);
	if (a->net)
		cJSON_AddNumberToObject(o, "net", a->net);
	snprintf(idx, sizeof idx, "0x%04X", a->index);
	cJSON_AddStringToObject(o, "index", idx);
	cJSON_AddNumberToObject(o, "sub", a->sub);
	return o;
}

/* One read of the object into buf (cap bytes): by the daemon's SDO
 * client, routed to another network, or from the daemon's own OD. */
static int read_once(ctl *c, cogw *h, const obj_args *a, uint8_t *buf, size_t cap, size_t *len,
		     uint32_t *abort)
{
	if (a->net)
		return cogw_sdo_read_net(h, a->line, a->net, a->node, a->index, a->sub, &a->opts,
					 buf, cap, len, c->timeout_ms, abort);
	if (a->remote)
		return cogw_sdo_read_ex(h, a->line, a->node, a->index, a->sub, &a->opts, buf, cap,
					len, c->timeout_ms, abort);
	return cogw_od_read(h, a->line, a->index, a->sub, buf, cap, len, c->timeout_ms, abort);
}

/* The answer into --out FILE ("-": stdout, then *done). */
static int save_answer(const obj_args *a, const uint8_t *buf, size_t len, bool *done)
{
	FILE *f = strcmp(a->out_path, "-") == 0 ? stdout : fopen(a->out_path, "wb");

	if (!f || fwrite(buf, 1, len, f) != len || (f != stdout && fclose(f) != 0)) {
		fprintf(stderr, "cogwctl: %s: %s\n", a->out_path, strerror(errno));
		return CTL_EXIT_REFUSED;
	}
	if (f == stdout) {
		fflush(stdout);
		*done = true;
	}
	return 0;
}

static void print_answer(ctl *c, const obj_args *a, const uint8_t *buf, size_t len)
{
	if (c->json) {
		cJSON *o = json_head(a);
		cJSON_AddNumberToObject(o, "size", (double)len);
		if (a->out_path)
			cJSON_AddStringToObject(o, "file", a->out_path);
		else
			ctl_value_json(o, a->type, buf, len);
		ctl_json_print(o);
	} else if (a->out_path) {
		printf("%04X:%02X: %zu bytes written to %s\n", a->index, a->sub, len, a->out_path);
	} else {
		char *text = ctl_value_text(a->type, buf, len);
		if (a->type && a->type->type == CO_T_VISIBLE_STRING)
			printf("%04X:%02X = \"%s\"\n", a->index, a->sub, text ? text : "");
		else
			printf("%04X:%02X = %s%s\n", a->index, a->sub, text ? text : "?",
			       !a->type && len > 8 ? "" : "");
		if (!a->type && len > 64)
			printf("(%zu bytes; --out FILE saves them all)\n", len);
		free(text);
	}
}

/* The answer's size fits the TYPE given (none: any). */
static int check_size(const obj_args *a, const char *ctx, const uint8_t *buf, size_t len)
{
	char *hex;

	if (!a->type || !a->type->size || len == a->type->size)
		return 0;
	hex = ctl_hex_text(buf, len, 16);
	fprintf(stderr, "cogwctl: %s: the answer has %zu byte%s (%s), %s needs %u\n", ctx, len,
		len == 1 ? "" : "s", hex, a->type->name, a->type->size);
	free(hex);
	return CTL_EXIT_REFUSED;
}

static int do_read(ctl *c, cogw *h, const obj_args *a)
{
	char ctx[96];
	context(a, false, ctx, sizeof ctx);
	size_t cap = sizeof first_answer, len = 0;
	uint8_t *buf = first_answer, *bigger = NULL;
	uint32_t abort = 0;
	bool done = false;
	int rc;
	for (int attempt = 0;; attempt++) {
		if (!buf) {
			fprintf(stderr, "cogwctl: out of memory\n");
			return CTL_EXIT_REFUSED;
		}
		rc = read_once(c, h, a, buf, cap, &len, &abort);
		if (rc != COGW_E_TRUNCATED || attempt > 0 || len <= cap)
			break;
		cap = len;
		buf = bigger = malloc(cap);
	}
	if (rc < 0)
		rc = ctl_fail(c, rc, abort, ctx);
	else if (!(rc = check_size(a, ctx, buf, len)) &&
		 !(a->out_path && (rc = save_answer(a, buf, len, &done))) && !done)
		print_answer(c, a, buf, len);
	free(bigger);
	return rc;
}

static int do_write(ctl *c, cogw *h, const obj_args *a, const char *value)
{
	char ctx[96];
	context(a, true, ctx, sizeof ctx);
	uint8_t *data;
	size_t len;
	int rc = ctl_value_encode(c, a->type, value, &data, &len);
	if (rc)
		return rc;
	uint32_t abort = 0;
	if (a->net)
		rc = cogw_sdo_write_net(h, a->line, a->net, a->node, a->index, a->sub, &a->opts,
					data, len, c->timeout_ms, &abort);
	else
		rc = a->remote ? cogw_sdo_write_ex(h, a->line, a->node, a->index, a->sub, &a->opts,
						   data, len, c->timeout_ms, &abort)
			       : cogw_od_write(h, a->line, a->index, a->sub, data, len,
					       c->timeout_ms, &abort);
	if (rc < 0) {
		free(data);
		return ctl_fail(c, rc, abort, ctx);
	}
	if (c->json) {
		cJSON *o = json_head(a);
		cJSON_AddNumberToObject(o, "size", (double)len);
		ctl_value_json(o, a->type, data, len);
		ctl_json_print(o);
	} else {
		char *text = value[0] == '@' ? NULL : ctl_value_text(a->type, data, len);
		printf("%04X:%02X <- %s (%zu byte%s): ok\n", a->index, a->sub, text ? text : value,
		       len, len == 1 ? "" : "s");
		free(text);
	}
	free(data);
	return 0;
}

static int parse_mode(ctl *c, const char *s, uint8_t *mode)
{
	static const char *const names[] = { "auto", "expedited", "segmented", "block" };
	for (uint8_t i = 0; i < 4; i++)
		if (strcmp(s, names[i]) == 0) {
			*mode = i;
			return 0;
		}
	return ctl_usage_error(c, "--mode '%s': one of auto, expedited, segmented, block", s);
}

/* The options of "sdo"/"od" as given (NULL: not given). */
struct obj_opts {
	const char *out, *mode, *sdo_timeout, *net;
};

/* LINE [NODE] INDEX SUB [TYPE] into a; *k moved past them. */
static int obj_positionals(ctl *c, const char **pos, int n_pos, bool write, obj_args *a, int *k)
{
	/* [remote][write]: od read, od write; sdo read, sdo write */
	static const char *const expected[2][2] = {
		{ "expected LINE INDEX SUB [TYPE]", "expected LINE INDEX SUB TYPE VALUE|@FILE" },
		{ "expected LINE NODE INDEX SUB [TYPE]",
		  "expected LINE NODE INDEX SUB TYPE VALUE|@FILE" },
	};
	bool remote = a->remote;
	int need = (remote ? 4 : 3) + (write ? 2 : 0);
	int most = write ? need : need + 1; /* a read may name a TYPE */
	if (n_pos - 1 < need || n_pos - 1 > most)
		return ctl_usage_error(c, "%s", expected[remote][write]);
	if (ctl_arg_line(c, pos[(*k)++], &a->line) < 0 ||
	    (remote && ctl_arg_node(c, pos[(*k)++], &a->node) < 0) ||
	    ctl_arg_index(c, pos[(*k)++], &a->index) < 0 ||
	    ctl_arg_sub(c, pos[(*k)++], &a->sub) < 0)
		return CTL_EXIT_USAGE;
	if (*k < n_pos) {
		a->type = ctl_type_find(pos[*k]);
		if (!a->type)
			return ctl_usage_error(c, "unknown TYPE '%s'; types: %s", pos[*k],
					       ctl_type_names());
		(*k)++;
	}
	return 0;
}

/* --out, --mode, --net and --sdo-timeout into a. */
static int obj_options(ctl *c, const struct obj_opts *o, bool write, obj_args *a)
{
	if (write && o->out)
		return ctl_usage_error(c, "--out is for read");
	if (o->mode && parse_mode(c, o->mode, &a->opts.mode))
		return CTL_EXIT_USAGE;
	if (o->net) {
		uint64_t v;
		if (ctl_arg_uint(c, o->net, "--net", 127, &v) < 0)
			return CTL_EXIT_USAGE;
		if (v < 1)
			return ctl_usage_error(c, "--net %s: a network id is 1..127", o->net);
		a->net = (uint16_t)v;
	}
	if (o->sdo_timeout) {
		uint64_t ms;
		if (ctl_arg_uint(c, o->sdo_timeout, "--sdo-timeout", 600000, &ms) < 0)
			return CTL_EXIT_USAGE;
		a->opts.sdo_timeout_ms = (uint32_t)ms;
	}
	return 0;
}

/* argv: "sdo" or "od", then read|write and the positionals. */
/*
 * "od import LINE FILE": every entry of a concise DCF written into the
 * daemon's own OD of the line, in the file's order (the CiA 302 manager's
 * objects, 1F81h:n last, configure a node at run time: docs/config.md
 * "Nodes at run time"). The first refusal stops it: its entry number,
 * index:sub and abort code, as the import of a concise DCF reports them.
 */
static int od_import(ctl *c, const char **pos, int n_pos)
{
	uint8_t *buf = NULL;
	size_t len = 0;
	unsigned line;
	char err[600], ctx[96];
	co_cdcf_iter it;
	co_cdcf_entry e;
	int ex = 0, rc;

	c->what = "od import";
	if (n_pos != 3)
		return ctl_usage_error(c, "expected import LINE FILE");
	if (ctl_arg_line(c, pos[1], &line) < 0)
		return CTL_EXIT_USAGE;
	if ((rc = cogw_cdcf_load_file(pos[2], &buf, &len, err, sizeof err))) {
		fprintf(stderr, "cogwctl %s: %s\n", c->what, err);
		return rc == -EINVAL ? CTL_EXIT_REFUSED : CTL_EXIT_USAGE;
	}
	cogw *h = ctl_handle(c, &ex);
	rc = h && !co_cdcf_iter_init(&it, buf, len, NULL) ? 0 : -1;
	while (!rc && co_cdcf_iter_next(&it, &e)) {
		uint32_t abort = 0;
		rc = cogw_od_write(h, line, e.index, e.sub, e.data, e.size, c->timeout_ms, &abort);
		if (rc < 0) {
			snprintf(ctx, sizeof ctx, "entry %" PRIu32 ", %04X:%02X on line %u",
				 e.number, e.index, e.sub, line);
			ex = ctl_fail(c, rc, abort, ctx);
		}
	}
	free(buf);
	if (!h || ex)
		return ex;
	printf("line %u: %" PRIu32 " entries written\n", line, it.count);
	return CTL_EXIT_OK;
}

static int run_obj(ctl *c, int argc, char **argv, bool remote, const ctl_cmd *self)
{
	const char *pos[8];
	int n_pos;
	struct obj_opts o = { 0 };
	ctl_opt sdo_opts[] = {
		{ "--out", true, &o.out, NULL },   { "--net", true, &o.net, NULL },
		{ "--mode", true, &o.mode, NULL }, { "--sdo-timeout", true, &o.sdo_timeout, NULL },
		{ NULL, false, NULL, NULL },
	};
	ctl_opt od_opts[] = {
		{ "--out", true, &o.out, NULL },
		{ NULL, false, NULL, NULL },
	};
	int rc = ctl_parse(c, argc, argv, remote ? sdo_opts : od_opts, pos, 8, &n_pos);
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(self);
	if (n_pos < 1)
		return ctl_usage_error(c, "read or write?");
	if (!remote && !strcmp(pos[0], "import"))
		return od_import(c, pos, n_pos);
	bool write = strcmp(pos[0], "write") == 0;
	if (!write && strcmp(pos[0], "read") != 0)
		return ctl_usage_error(c, "unknown action '%s' (read or write)", pos[0]);
	c->what = remote ? (write ? "sdo write" : "sdo read") : (write ? "od write" : "od read");

	obj_args a = { .remote = remote, .out_path = o.out };
	int k = 1;
	if ((rc = obj_positionals(c, pos, n_pos, write, &a, &k)) ||
	    (rc = obj_options(c, &o, write, &a)))
		return rc;
	int ex = 0;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	return write ? do_write(c, h, &a, pos[k]) : do_read(c, h, &a);
}

static int run_sdo(ctl *c, int argc, char **argv)
{
	return run_obj(c, argc, argv, true, &ctl_cmd_sdo);
}

static int run_od(ctl *c, int argc, char **argv)
{
	return run_obj(c, argc, argv, false, &ctl_cmd_od);
}

const ctl_cmd ctl_cmd_sdo = {
	.name = "sdo",
	.synopsis =
		"  sdo read LINE NODE INDEX SUB [TYPE]      read an object of a node (SDO upload)\n"
		"  sdo write LINE NODE INDEX SUB TYPE VALUE|@FILE\n"
		"                                           write an object of a node (SDO "
		"download)\n",
	.help = "usage: cogwctl sdo read LINE NODE INDEX SUB [TYPE] [--out FILE] [--mode M] "
		"[--sdo-timeout MS]\n"
		"                        [--net NET]\n"
		"       cogwctl sdo write LINE NODE INDEX SUB TYPE VALUE|@FILE [--mode M] "
		"[--sdo-timeout MS]\n"
		"                        [--net NET]\n"
		"\n"
		"The daemon reads (uploads) or writes (downloads) object INDEX:SUB of node NODE "
		"on\n"
		"line LINE with its SDO client. Any size: expedited, segmented or block transfer\n"
		"as the size requires (the daemon's limit is 1 MiB by default).\n"
		"\n"
		"  INDEX          hex: 1018, 0x1018 or 1018h\n"
		"  SUB            0..255, decimal or 0x hex\n"
		"  TYPE           how to show (read) or encode (write) the value:\n"
		"                 bool, u8..u64 (also u24/u40/u48/u56), i8..i64, r32, r64,\n"
		"                 string (VISIBLE_STRING), hex (OCTET_STRING), domain; the CiA\n"
		"                 names (UNSIGNED32, REAL32, ...) work too. Without TYPE a read\n"
		"                 prints the bytes in hex and, for 1/2/4/8 bytes, the unsigned "
		"value.\n"
		"  VALUE          integers decimal or 0x hex, range-checked for the type; reals "
		"as\n"
		"                 decimal numbers; bool 0/1/true/false; string as given; hex and\n"
		"                 domain as hex bytes (\"01 02 ff\" or 0102ff)\n"
		"  @FILE          (string, hex, domain) the value is the contents of FILE\n"
		"  --out FILE     (read) write the raw bytes to FILE ('-' = stdout, for pipes)\n"
		"  --mode M       auto (default), expedited, segmented or block\n"
		"  --sdo-timeout MS  per-frame SDO timeout on the bus (default: the line's, 1000)\n"
		"  --net NET      node NODE of network NET (1..127), wherever it is: the daemon's\n"
		"                 gateway routes the transfer by LINE's routing table 1F2Ch, to "
		"the\n"
		"                 line that network is attached to or through the next router\n"
		"                 (docs/gateway.md). Refusals: abort 0x0A000001 (no route),\n"
		"                 0x0A000002 (no answer), 0x060A0023 (no SDO client free)\n"
		"\n"
		"An SDO abort is printed with its CiA 301 meaning and exits 1, e.g.\n"
		"  cogwctl sdo read: SDO upload 2001:00 node 1 on line 0: abort 0x06020000 (object "
		"does not exist)\n"
		"A node that does not answer gives abort 0x05040000 (SDO protocol timed out) and "
		"exit 4.\n"
		"For large transfers raise --timeout (the whole exchange with the daemon).\n"
		"\n"
		"Examples:\n"
		"  cogwctl sdo read 0 1 1018 1 u32            vendor-ID of node 1 on line 0\n"
		"  cogwctl sdo read 0 1 1008 0 string         device name\n"
		"  cogwctl sdo write 0 1 1017 0 u16 500       heartbeat every 500 ms\n"
		"  cogwctl sdo write 0 1 2005 1 r32 98.5\n"
		"  cogwctl sdo write 0 5 2100 0 domain @firmware.bin --mode block --timeout 60000\n"
		"  cogwctl sdo read 0 5 2100 0 domain --out dump.bin\n"
		"  cogwctl sdo read 0 2 1018 1 u32 --net 2   node 2 of network 2, asked on line "
		"0\n",
	.run = run_sdo,
};

const ctl_cmd ctl_cmd_od = {
	.name = "od",
	.synopsis =
		"  od read|write LINE INDEX SUB [TYPE] [VALUE]\n"
		"  od import LINE FILE.cdc                  the daemon's own object dictionary\n",
	.help = "usage: cogwctl od read LINE INDEX SUB [TYPE] [--out FILE]\n"
		"       cogwctl od write LINE INDEX SUB TYPE VALUE|@FILE\n"
		"       cogwctl od import LINE FILE.cdc\n"
		"\n"
		"Read or write an object of the daemon's own object dictionary on line LINE (the\n"
		"manager's node on that line: 1017h heartbeat, 1016h consumers, PDO parameters,\n"
		"the B000h process image, ...). INDEX, SUB, TYPE, VALUE and --out as for 'sdo'.\n"
		"A refusal is an SDO abort code with its meaning (exit 1).\n"
		"'import' writes every entry of a concise DCF (CiA 302-3) in its order, e.g. the\n"
		"manager's objects of a node (1F84h..1F88h:n, 1016h, 1F81h:n last) to add it at\n"
		"run time; the first refusal stops it and names the entry.\n"
		"\n"
		"Examples:\n"
		"  cogwctl od read 0 1017 0 u16\n"
		"  cogwctl od read 0 1008 0 string\n"
		"  cogwctl od write 0 1017 0 u16 2000\n",
	.run = run_od,
};
