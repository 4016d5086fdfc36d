/* SPDX-License-Identifier: MIT */
/*
 * cogwctl dcf - offline: check a CiA 306 DCF/EDS (or a binary concise
 * DCF) and convert a DCF/EDS into the concise DCF that the configuration
 * manager downloads. No daemon involved; the same reader as cogwd's
 * node configuration (apps/common/eds.c, node_config.c), so what passes
 * here loads there.
 */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "apps/cogwctl/ctl.h"
#include "apps/common/eds.h"
#include "apps/common/node_config.h"
#include "core/cdcf.h"

static bool is_concise_name(const char *path)
{
	const char *dot = strrchr(path, '.');
	return dot && (!strcmp(dot, ".cdc") || !strcmp(dot, ".bin"));
}

/* "file: reason" on stderr, or {"ok":false,...} with --json. */
static int refuse(ctl *c, const char *file, const char *msg)
{
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddBoolToObject(o, "ok", false);
		cJSON_AddStringToObject(o, "file", file);
		cJSON_AddStringToObject(o, "error", msg);
		ctl_json_print(o);
	} else {
		fprintf(stderr, "cogwctl %s: %s\n", c->what, msg);
	}
	return CTL_EXIT_REFUSED;
}

static void list_entries(ctl *c, cJSON *o, const uint8_t *buf, size_t len)
{
	cJSON *arr = o ? cJSON_AddArrayToObject(o, "entries") : NULL;
	co_cdcf_iter it;
	co_cdcf_entry e;

	if (co_cdcf_iter_init(&it, buf, len, NULL))
		return;
	while (co_cdcf_iter_next(&it, &e)) {
		char *hex = ctl_hex_text(e.data, e.size, 16);
		if (c->json) {
			cJSON *x = cJSON_CreateObject();
			char idx[8];
			snprintf(idx, sizeof idx, "%04X", e.index);
			cJSON_AddStringToObject(x, "index", idx);
			cJSON_AddNumberToObject(x, "sub", e.sub);
			cJSON_AddNumberToObject(x, "size", e.size);
			cJSON_AddStringToObject(x, "hex", hex ? hex : "");
			cJSON_AddItemToArray(arr, x);
		} else {
			printf("  %4u  %04X:%02X  %6u bytes  %s\n", (unsigned)e.number, e.index,
			       e.sub, (unsigned)e.size, hex ? hex : "");
		}
		free(hex);
	}
}

/* The warnings of one conversion, "file:line: reason" each (the first
 * WARNINGS_KEPT of them), for stderr or --json. */
#define WARNINGS_KEPT 100

typedef struct warnings {
	cJSON *list;
	unsigned count;
} warnings;

static void on_warning(void *arg, const char *text)
{
	warnings *w = arg;

	if (w->count++ < WARNINGS_KEPT)
		cJSON_AddItemToArray(w->list, cJSON_CreateString(text));
}

static void print_warnings(const warnings *w)
{
	const cJSON *item;

	cJSON_ArrayForEach(item, w->list) fprintf(stderr, "warning: %s\n", item->valuestring);
	if (w->count > 1)
		fprintf(stderr, "warning: %u warnings in all%s\n", w->count,
			w->count > WARNINGS_KEPT ? " (the first ones are shown)" : "");
}

/*
 * Convert FILE (opts->node_id 0 = the file's own NodeID). For a check
 * without --node, a file that needs $NODEID is checked with node 1 and
 * says so.
 */
static int convert(ctl *c, const char *file, eds_options *opts, bool check, eds_result *res,
		   bool *assumed_node)
{
	const char *err = res->err;
	warnings *w = opts->warning_arg;
	int rc = eds_convert_file_opts(file, opts, res);

	*assumed_node = false;
	if (rc == -EINVAL && check && !opts->node_id && strstr(err, "$NODEID needs a node id")) {
		*assumed_node = true;
		opts->node_id = 1;
		while (cJSON_GetArraySize(w->list))
			cJSON_DeleteItemFromArray(w->list, 0);
		w->count = 0;
		rc = eds_convert_file_opts(file, opts, res);
	}
	if (rc == -EINVAL && !c->json)
		print_warnings(w); /* what came before the refusal */
	if (rc == -ENOMEM) {
		fprintf(stderr, "cogwctl %s: out of memory\n", c->what);
		return CTL_EXIT_REFUSED;
	}
	if (rc == -EINVAL)
		return refuse(c, file, err);
	if (rc) /* the file could not be read */
		return c->json ? refuse(c, file, err)
			       : (fprintf(stderr, "cogwctl %s: %s\n", c->what, err),
				  CTL_EXIT_USAGE);
	return 0;
}

static int check_concise(ctl *c, const char *file, bool list)
{
	uint8_t *buf = NULL;
	size_t len = 0;
	char err[400];
	uint32_t count = 0;
	int rc = cogw_cdcf_load_file(file, &buf, &len, err, sizeof err);

	if (rc == -EINVAL)
		return refuse(c, file, err);
	if (rc) {
		fprintf(stderr, "cogwctl %s: %s\n", c->what, err);
		return rc == -ENOMEM ? CTL_EXIT_REFUSED : CTL_EXIT_USAGE;
	}
	co_cdcf_check(buf, len, &count, NULL);
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddBoolToObject(o, "ok", true);
		cJSON_AddStringToObject(o, "file", file);
		cJSON_AddStringToObject(o, "format", "concise");
		cJSON_AddNumberToObject(o, "entries", count);
		cJSON_AddNumberToObject(o, "bytes", (double)len);
		if (list)
			list_entries(c, o, buf, len);
		ctl_json_print(o);
	} else {
		printf("%s: concise DCF ok: %u entries, %zu bytes\n", file, (unsigned)count, len);
		if (list)
			list_entries(c, NULL, buf, len);
	}
	free(buf);
	return CTL_EXIT_OK;
}

/* Write the whole buffer to path through a temporary file and rename, so
 * a reader never sees half a file. */
static int write_file(ctl *c, const char *path, const uint8_t *buf, size_t len)
{
	char tmp[4096];
	int fd;
	size_t done = 0;

	if (snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid()) >= (int)sizeof tmp)
		return ctl_usage_error(c, "output path too long");
	fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
	if (fd < 0) {
		fprintf(stderr, "cogwctl %s: %s: %s\n", c->what, tmp, strerror(errno));
		return CTL_EXIT_USAGE;
	}
	while (done < len) {
		ssize_t n = write(fd, buf + done, len - done);
		if (n < 0 && errno == EINTR)
			continue;
		if (n <= 0)
			break;
		done += (size_t)n;
	}
	if (done != len || fsync(fd) < 0 || close(fd) < 0 || rename(tmp, path) < 0) {
		fprintf(stderr, "cogwctl %s: cannot write %s: %s\n", c->what, path,
			strerror(errno));
		unlink(tmp);
		return CTL_EXIT_REFUSED;
	}
	return 0;
}

static void report(ctl *c, const char *file, const char *out_s, const uint8_t *buf, size_t len,
		   const eds_stats *st, bool assumed, warnings *w, bool list)
{
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddBoolToObject(o, "ok", true);
		cJSON_AddStringToObject(o, "file", file);
		if (out_s)
			cJSON_AddStringToObject(o, "output", out_s);
		cJSON_AddNumberToObject(o, "objects", st->objects);
		cJSON_AddNumberToObject(o, "values", st->values);
		cJSON_AddNumberToObject(o, "entries", st->entries);
		cJSON_AddNumberToObject(o, "without_value", st->skipped);
		cJSON_AddNumberToObject(o, "bytes", (double)len);
		if (st->node_id)
			cJSON_AddNumberToObject(o, "node", st->node_id);
		cJSON_AddBoolToObject(o, "node_assumed", assumed);
		cJSON_AddNumberToObject(o, "warnings", st->warnings);
		if (st->warnings)
			cJSON_AddStringToObject(o, "first_warning", st->first_warning);
		cJSON_AddItemToObject(o, "warning_list", w->list);
		w->list = NULL;
		if (list)
			list_entries(c, o, buf, len);
		ctl_json_print(o);
		return;
	}
	print_warnings(w);
	if (assumed)
		printf("note: $NODEID evaluated as 1 (give --node N for the real node)\n");
	printf("%s: ok: %u objects, %u values, %u entries for the concise DCF (%zu "
	       "bytes)%s",
	       file, st->objects, st->values, st->entries, len, st->node_id ? "" : "\n");
	if (st->node_id)
		printf(", node %u\n", st->node_id);
	if (out_s)
		printf("wrote %s\n", out_s);
	if (list)
		list_entries(c, NULL, buf, len);
}

/* The options of "dcf" as given. */
struct dcf_opts {
	const char *node, *out, *out_long;
	bool list, strict;
};

/* The action and the options checked against each other; *check for
 * "check", the node-ID into *node, -o into o->out. */
static int dcf_args(ctl *c, const char **pos, int n_pos, struct dcf_opts *o, bool *check,
		    uint8_t *node)
{
	if (n_pos < 1)
		return ctl_usage_error(c, "check or convert?");
	*check = !strcmp(pos[0], "check");
	if (!*check && strcmp(pos[0], "convert"))
		return ctl_usage_error(c, "unknown action '%s' (check or convert)", pos[0]);
	c->what = *check ? "dcf check" : "dcf convert";
	if (n_pos != 2)
		return ctl_usage_error(c, n_pos < 2 ? "FILE missing" : "one FILE only");
	if (o->out_long)
		o->out = o->out_long;
	if (o->node && ctl_arg_node(c, o->node, node))
		return CTL_EXIT_USAGE;
	if (*check && o->out)
		return ctl_usage_error(c, "-o belongs to 'dcf convert'");
	if (!*check && !o->out)
		return ctl_usage_error(c, "-o FILE.cdc missing");
	return 0;
}

static int run_dcf(ctl *c, int argc, char **argv)
{
	const char *pos[4];
	struct dcf_opts o = { 0 };
	int n_pos;
	ctl_opt opts[] = {
		{ "--node", true, &o.node, NULL },       { "-o", true, &o.out, NULL },
		{ "--output", true, &o.out_long, NULL }, { "--list", false, NULL, &o.list },
		{ "--strict", false, NULL, &o.strict },  { NULL, false, NULL, NULL }
	};
	int rc = ctl_parse(c, argc, argv, opts, pos, 4, &n_pos);
	uint8_t node = 0;
	eds_result res = { 0 };
	bool assumed, check = false;
	warnings w = { 0 };
	eds_options eo = { .on_warning = on_warning, .warning_arg = &w };

	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_dcf);
	if ((rc = dcf_args(c, pos, n_pos, &o, &check, &node)))
		return rc;
	if (check && is_concise_name(pos[1]))
		return check_concise(c, pos[1], o.list);

	eo.node_id = node;
	eo.strict = o.strict;
	w.list = cJSON_CreateArray();
	if (!w.list) {
		fprintf(stderr, "cogwctl %s: out of memory\n", c->what);
		return CTL_EXIT_REFUSED;
	}
	rc = convert(c, pos[1], &eo, check, &res, &assumed);
	if (!rc && !check)
		rc = write_file(c, o.out, res.cdcf, res.len);
	if (!rc)
		report(c, pos[1], check ? NULL : o.out, res.cdcf, res.len, &res.stats, assumed, &w,
		       o.list);
	cJSON_Delete(w.list);
	free(res.cdcf);
	return rc ? rc : CTL_EXIT_OK;
}

const ctl_cmd ctl_cmd_dcf = {
	.name = "dcf",
	.synopsis =
		"  dcf check FILE [--node N] [--list] [--strict]\n"
		"                                           validate a DCF/EDS or a concise DCF "
		"(offline)\n"
		"  dcf convert FILE --node N -o OUT.cdc [--strict]\n"
		"                                           DCF/EDS to a concise DCF (offline)\n",
	.help = "usage: cogwctl dcf check FILE [--node N] [--list] [--strict]\n"
		"       cogwctl dcf convert FILE [--node N] -o OUT.cdc [--list] [--strict]\n"
		"\n"
		"Offline (no daemon): the same reader as cogwd's \"nodes[].config\" "
		"(docs/config.md,\n"
		"\"DCF and EDS files\"), so a file that passes here loads there.\n"
		"\n"
		"check    reads a CiA 306 DCF or EDS, checks every section and value (types, "
		"ranges,\n"
		"         limits, $NODEID expressions, sub-objects, CompactSubObj, ObjectLinks) "
		"and\n"
		"         says how many entries its concise DCF has. A FILE ending in .cdc or .bin "
		"is\n"
		"         checked as a binary concise DCF instead (count, entry framing).\n"
		"convert  writes the concise DCF (1F22h format) of the writable values to "
		"OUT.cdc,\n"
		"         PDO parameters in the CiA 301 re-mapping order.\n"
		"\n"
		"--node N   what $NODEID stands for (1..127); default: the file's\n"
		"           [DeviceComissioning] NodeID. check without either evaluates $NODEID\n"
		"           as 1 and says so.\n"
		"-o FILE    output of convert (written to a temporary file, then renamed)\n"
		"--list     print the entries: number, index:sub, size, data\n"
		"\n"
		"Files are read as python-canopen and the CANopenNode editor read them: what is\n"
		"inconsistent but usable is a warning with file:line (a SubNumber that disagrees\n"
		"with the sub-object sections, a default value that cannot be used and is left\n"
		"out, a tab or UTF-8 in a VISIBLE_STRING, a listed object without a section, ...)\n"
		"and the file is used; only what cannot be used is refused, e.g.\n"
		"  cogwctl dcf check: dev.dcf:41: ParameterValue '70000': out of range for "
		"UNSIGNED16 (max 65535)\n"
		"--strict   refuse what is otherwise a warning (except the object lists)\n"
		"Exit status 1 for a refused file. The full rules: docs/config.md.\n"
		"\n"
		"Examples:\n"
		"  cogwctl dcf check etc/transducer.dcf --list\n"
		"  cogwctl dcf convert vendor.eds --node 5 -o node5.cdc\n"
		"  cogwctl dcf check node5.cdc\n",
	.run = run_dcf,
};
