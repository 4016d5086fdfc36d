/* SPDX-License-Identifier: MIT */
/*
 * cogwctl pdo map, watch and dev: the line's slaves by their own objects
 * (docs/devices.md) - the PDO layouts the daemon learnt and mirrors,
 * watching a device object's typed values, reading and writing one by
 * PDO or SDO as the daemon chooses.
 */
#include <inttypes.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "apps/cogwctl/ctl.h"

static const char *mirror_status_text(uint8_t s)
{
	static const char *const names[] = { "off", "waiting", "full", "partial", "none" };
	return s < 5 ? names[s] : "?";
}

static const char *mirror_reason_text(uint8_t r)
{
	static const char *const names[] = { "", "no free PDO of the daemon", "COB-ID in use",
					     "OD refused", "not kept" };
	return r < 5 ? names[r] : "?";
}

static const char *source_text(uint8_t s)
{
	return s == 1 ? "file" : s == 2 ? "scan" : "none";
}

static const char *type_text(uint16_t type)
{
	const ctl_type *t = cogw_type_of(type);
	return t ? t->cia_name : "-";
}

/* ---- pdo map ------------------------------------------------------------------ */

/* A node's heading: a JSON object with an empty "pdos" (returned), or a
 * line of text (NULL). */
static cJSON *layout_heading(ctl *c, unsigned line, const mbx_dev_layout_node *n)
{
	cJSON *o;

	if (!c->json) {
		printf("line %u node %u: layout %s%s (generation %" PRIu32 "), mirror %s", line,
		       n->node, source_text(n->source), n->valid ? "" : " (not valid)",
		       n->generation, mirror_status_text(n->mirror));
		if (n->missing)
			printf(", %u PDO%s not mirrored: %s", n->missing,
			       n->missing == 1 ? "" : "s", mirror_reason_text(n->reason));
		if (n->dropped_tpdo || n->dropped_rpdo)
			printf(", %u TPDOs and %u RPDOs beyond the table's room", n->dropped_tpdo,
			       n->dropped_rpdo);
		printf("\n");
		return NULL;
	}
	o = cJSON_CreateObject();
	cJSON_AddNumberToObject(o, "line", line);
	cJSON_AddNumberToObject(o, "node", n->node);
	cJSON_AddStringToObject(o, "source", source_text(n->source));
	cJSON_AddBoolToObject(o, "valid", n->valid);
	cJSON_AddNumberToObject(o, "generation", n->generation);
	cJSON_AddStringToObject(o, "mirror", mirror_status_text(n->mirror));
	if (n->missing) {
		cJSON_AddNumberToObject(o, "missing", n->missing);
		cJSON_AddStringToObject(o, "reason", mirror_reason_text(n->reason));
	}
	cJSON_AddNumberToObject(o, "dropped_tpdo", n->dropped_tpdo);
	cJSON_AddNumberToObject(o, "dropped_rpdo", n->dropped_rpdo);
	cJSON_AddArrayToObject(o, "pdos");
	return o;
}

/* One PDO's heading: into pdos (its "map" array returned), or a line of
 * text (pdos NULL, NULL returned). */
static cJSON *layout_pdo(cJSON *pdos, const mbx_dev_layout_pdo *p)
{
	cJSON *jp;

	if (!pdos) {
		char mirror[64] = "not mirrored";
		if (p->mirror_pdo)
			snprintf(mirror, sizeof mirror, "%s %u of the daemon",
				 p->dir ? "RPDO" : "TPDO", p->mirror_pdo);
		else if (p->mirror_reason)
			snprintf(mirror, sizeof mirror, "not mirrored: %s",
				 mirror_reason_text(p->mirror_reason));
		printf("  %s %-3u COB-ID %03" PRIX32 "h type %3u event %5u ms %u bytes  %s\n",
		       p->dir ? "TPDO" : "RPDO", p->nr, p->cob, p->tt, p->event_ms, p->bytes,
		       mirror);
		return NULL;
	}
	jp = cJSON_CreateObject();
	cJSON_AddStringToObject(jp, "pdo", p->dir ? "tpdo" : "rpdo");
	cJSON_AddNumberToObject(jp, "nr", p->nr);
	cJSON_AddNumberToObject(jp, "cob_id", p->cob);
	cJSON_AddNumberToObject(jp, "transmission_type", p->tt);
	cJSON_AddNumberToObject(jp, "event_ms", p->event_ms);
	cJSON_AddNumberToObject(jp, "bytes", p->bytes);
	cJSON_AddNumberToObject(jp, "mirror_pdo", p->mirror_pdo);
	if (p->mirror_reason)
		cJSON_AddStringToObject(jp, "not_mirrored", mirror_reason_text(p->mirror_reason));
	cJSON_AddItemToArray(pdos, jp);
	return cJSON_AddArrayToObject(jp, "map");
}

/* One mapped object: into jentries, or a line of text (jentries NULL). */
static void layout_entry(cJSON *jentries, const mbx_dev_layout_entry *e)
{
	cJSON *je;

	if (!jentries) {
		printf("    %04X:%02X %2u bits at bit %2u  %s\n", e->index, e->sub, e->bits,
		       e->offset, type_text(e->type));
		return;
	}
	je = cJSON_CreateObject();
	cJSON_AddNumberToObject(je, "index", e->index);
	cJSON_AddNumberToObject(je, "sub", e->sub);
	cJSON_AddNumberToObject(je, "bits", e->bits);
	cJSON_AddNumberToObject(je, "offset", e->offset);
	if (e->type)
		cJSON_AddStringToObject(je, "type", type_text(e->type));
	cJSON_AddItemToArray(jentries, je);
}

/* One node of a DEV_LAYOUT answer from *off: printed, *off moved on. */
static void print_layout_node(ctl *c, unsigned line, const uint8_t *buf, size_t *off)
{
	mbx_dev_layout_node n;
	memcpy(&n, buf + *off, sizeof n);
	*off += sizeof n;
	cJSON *o = layout_heading(c, line, &n);
	cJSON *pdos = o ? cJSON_GetObjectItem(o, "pdos") : NULL;

	for (unsigned k = 0; k < (unsigned)n.n_tpdo + n.n_rpdo; k++) {
		mbx_dev_layout_pdo p;
		memcpy(&p, buf + *off, sizeof p);
		*off += sizeof p;
		cJSON *jentries = layout_pdo(pdos, &p);
		for (unsigned i = 0; i < p.n; i++) {
			mbx_dev_layout_entry e;
			memcpy(&e, buf + *off, sizeof e);
			*off += sizeof e;
			layout_entry(jentries, &e);
		}
	}
	if (o)
		ctl_json_print(o);
}

static int layout_of_line(ctl *c, cogw *h, unsigned line, uint8_t node)
{
	size_t cap = 1u << 20, len = 0;
	uint8_t *buf = malloc(cap);
	char ctx[64];
	if (!buf)
		return ctl_fail(c, COGW_E_NOMEM, 0, "pdo map");
	snprintf(ctx, sizeof ctx, "PDO layouts on line %u", line);
	int rc = cogw_dev_layout(h, line, node, buf, cap, &len, c->timeout_ms);
	if (rc == 0 && cogw_dev_layout_check(buf, len) < 0)
		rc = COGW_E_PROTOCOL;
	if (rc < 0) {
		free(buf);
		return ctl_fail(c, rc, 0, ctx);
	}
	if (len == 0 && !c->json)
		printf("line %u: no node with a PDO layout (set \"pdo\" or \"eds\" in its "
		       "configuration)\n",
		       line);
	for (size_t off = 0; off < len;)
		print_layout_node(c, line, buf, &off);
	free(buf);
	return 0;
}

int ctl_pdo_map(ctl *c, int n_pos, const char **pos)
{
	unsigned line = 0;
	uint8_t node = 0;
	int ex = 0;
	c->what = "pdo map";
	if (n_pos > 3)
		return ctl_usage_error(c, "expected [LINE [NODE]]");
	if (n_pos >= 2 && ctl_arg_line(c, pos[1], &line) < 0)
		return CTL_EXIT_USAGE;
	if (n_pos == 3 && ctl_arg_node(c, pos[2], &node) < 0)
		return CTL_EXIT_USAGE;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	if (n_pos >= 2)
		return layout_of_line(c, h, line, node);
	int n = ctl_count_lines(c);
	if (n < 0)
		return -n;
	for (unsigned l = 0; l < (unsigned)n; l++)
		if ((ex = layout_of_line(c, h, l, 0)) != 0)
			return ex;
	return 0;
}

/* ---- the object arguments ------------------------------------------------------- */

typedef struct dev_args {
	unsigned line;
	mbx_dev_obj_req obj;
	const ctl_type *type;
} dev_args;

/* LINE NODE INDEX SUB [TYPE] from pos[0..]. */
static int parse_object(ctl *c, const char **pos, int n, dev_args *a)
{
	memset(a, 0, sizeof *a);
	if (ctl_arg_line(c, pos[0], &a->line) < 0 || ctl_arg_node(c, pos[1], &a->obj.node) < 0 ||
	    ctl_arg_index(c, pos[2], &a->obj.index) < 0 || ctl_arg_sub(c, pos[3], &a->obj.sub) < 0)
		return CTL_EXIT_USAGE;
	if (n >= 5) {
		if (!(a->type = ctl_type_find(pos[4])))
			return ctl_usage_error(c, "unknown TYPE '%s'; types: %s", pos[4],
					       ctl_type_names());
		a->obj.type = a->type->type;
	}
	return 0;
}

static void context(const dev_args *a, const char *what, char *buf, size_t len)
{
	snprintf(buf, len, "%s %04X:%02X of node %u on line %u", what, a->obj.index, a->obj.sub,
		 a->obj.node, a->line);
}

static cJSON *json_object_head(const dev_args *a)
{
	cJSON *o = cJSON_CreateObject();
	cJSON_AddBoolToObject(o, "ok", true);
	cJSON_AddNumberToObject(o, "line", a->line);
	cJSON_AddNumberToObject(o, "node", a->obj.node);
	cJSON_AddNumberToObject(o, "index", a->obj.index);
	cJSON_AddNumberToObject(o, "sub", a->obj.sub);
	return o;
}

/* ---- watch -------------------------------------------------------------------------- */

static volatile sig_atomic_t watch_stop;

static void on_watch_signal(int sig)
{
	(void)sig;
	watch_stop = 1;
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec / 1e9;
}

#define WATCH_MAX 256

/* Every object the mirrored TPDOs of node a->obj.node carry (dummies
 * aside): into objs, their count (or -exit code). */
static int node_objects(ctl *c, cogw *h, const dev_args *a, mbx_dev_obj_req *objs)
{
	size_t cap = 1u << 20, len = 0;
	uint8_t *buf = malloc(cap);
	int n = 0;
	char ctx[64];
	snprintf(ctx, sizeof ctx, "PDO layout of node %u on line %u", a->obj.node, a->line);
	if (!buf)
		return -ctl_fail(c, COGW_E_NOMEM, 0, ctx);
	int rc = cogw_dev_layout(h, a->line, a->obj.node, buf, cap, &len, c->timeout_ms);
	if (rc == 0 && cogw_dev_layout_check(buf, len) != 1)
		rc = COGW_E_PROTOCOL;
	if (rc < 0) {
		free(buf);
		return -ctl_fail(c, rc, 0, ctx);
	}
	mbx_dev_layout_node nd;
	memcpy(&nd, buf, sizeof nd);
	size_t off = sizeof nd;
	for (unsigned k = 0; k < (unsigned)nd.n_tpdo + nd.n_rpdo; k++) {
		mbx_dev_layout_pdo p;
		memcpy(&p, buf + off, sizeof p);
		off += sizeof p;
		for (unsigned i = 0; i < p.n; i++, off += sizeof(mbx_dev_layout_entry)) {
			mbx_dev_layout_entry e;
			memcpy(&e, buf + off, sizeof e);
			if (!p.dir || !p.mirror_pdo || e.index <= 0x0007u || n >= WATCH_MAX)
				continue;
			objs[n++] = (mbx_dev_obj_req){ .node = a->obj.node,
						       .index = e.index,
						       .sub = e.sub };
		}
	}
	free(buf);
	if (n == 0)
		return -ctl_usage_error(c,
					"node %u on line %u has no mirrored TPDO ('cogwctl pdo "
					"map %u %u' says why)",
					a->obj.node, a->line, a->line, a->obj.node);
	return n;
}

/* What "watch" watches and for how long. */
struct watch_run {
	dev_args a;
	uint64_t interval_ms, max, seconds; /* 0: no limit */
	mbx_dev_obj_req *objs;
	int n;
};

/* Each object of w registered with the daemon, and said on stderr. */
static int watch_register(ctl *c, cogw *h, const struct watch_run *w)
{
	for (int i = 0; i < w->n; i++) {
		char ctx[96];
		dev_args one = { .line = w->a.line, .obj = w->objs[i] };
		context(&one, "watch", ctx, sizeof ctx);
		mbx_dev_watch_resp resp;
		uint32_t abort = 0;
		int rc = cogw_dev_watch(h, w->a.line, &w->objs[i], (uint32_t)w->interval_ms, &resp,
					c->timeout_ms, &abort);
		if (rc < 0)
			return ctl_fail(c, rc, abort, ctx);
		fprintf(stderr,
			"cogwctl watch: node %u %04X:%02X as %s, carried by its TPDO %u (COB-ID "
			"%03" PRIX32 "h)\n",
			w->objs[i].node, w->objs[i].index, w->objs[i].sub, type_text(resp.type),
			resp.pdo, resp.cob_id);
	}
	fprintf(stderr, "cogwctl watch: watching %d object%s\n", w->n, w->n == 1 ? "" : "s");
	return 0;
}

/* The values printed as they come, until a signal, the count or the
 * duration ends the watch. */
static int watch_loop(ctl *c, cogw *h, const struct watch_run *w)
{
	struct sigaction sa = { .sa_handler = on_watch_signal }; /* no SA_RESTART */
	sigemptyset(&sa.sa_mask);
	sigaction(SIGINT, &sa, NULL);
	sigaction(SIGTERM, &sa, NULL);
	ctl_monitor_spec spec = { 0 };
	double start = now_s();
	uint64_t seen = 0;
	while (!watch_stop && (!w->max || seen < w->max)) {
		double left = w->seconds ? (double)w->seconds - (now_s() - start) : 0.2;
		if (left <= 0)
			break;
		cogw_msg m;
		int rc = cogw_recv(h, &m, left > 0.2 ? 200 : (int)(left * 1000) + 1);
		if (rc == COGW_E_AGAIN)
			continue;
		if (rc < 0)
			return ctl_fail(c, rc, 0, "receiving values");
		if (m.kind == MBX_KIND_EVENT && m.line == w->a.line &&
		    (m.code == MBX_EV_DEV_VALUE || m.code == MBX_EV_OVERFLOW)) {
			ctl_monitor_print(c, &m, &spec);
			seen += m.code == MBX_EV_DEV_VALUE;
		}
		cogw_msg_release(&m);
	}
	return 0;
}

/* LINE NODE [INDEX SUB [TYPE]] and the options into w. */
static int watch_args(ctl *c, const char **pos, int n_pos, const char *const opt[3],
		      struct watch_run *w)
{
	int rc;

	if (n_pos != 2 && (n_pos < 4 || n_pos > 5))
		return ctl_usage_error(c, "expected LINE NODE [INDEX SUB [TYPE]]");
	if (n_pos == 2) {
		memset(&w->a, 0, sizeof w->a);
		if (ctl_arg_line(c, pos[0], &w->a.line) < 0 ||
		    ctl_arg_node(c, pos[1], &w->a.obj.node) < 0)
			return CTL_EXIT_USAGE;
	} else if ((rc = parse_object(c, pos, n_pos, &w->a))) {
		return rc;
	}
	if ((opt[0] && ctl_arg_uint(c, opt[0], "--interval", UINT32_MAX, &w->interval_ms) < 0) ||
	    (opt[1] && ctl_arg_uint(c, opt[1], "--count", UINT32_MAX, &w->max) < 0) ||
	    (opt[2] && ctl_arg_uint(c, opt[2], "--duration", 86400, &w->seconds) < 0))
		return CTL_EXIT_USAGE;
	return 0;
}

static int run_watch(ctl *c, int argc, char **argv)
{
	const char *pos[6], *opt[3] = { NULL, NULL, NULL };
	int n_pos;
	ctl_opt opts[] = { { "--interval", true, &opt[0], NULL },
			   { "--count", true, &opt[1], NULL },
			   { "--duration", true, &opt[2], NULL },
			   { NULL, false, NULL, NULL } };
	static mbx_dev_obj_req objs[WATCH_MAX];
	struct watch_run w = { .objs = objs, .n = 1 };
	int rc = ctl_parse(c, argc, argv, opts, pos, 6, &n_pos);
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_watch);
	c->what = "watch";
	if ((rc = watch_args(c, pos, n_pos, opt, &w)))
		return rc;

	int ex = 0;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	objs[0] = w.a.obj;
	if (n_pos == 2 && (w.n = node_objects(c, h, &w.a, objs)) < 0)
		return -w.n;
	if ((rc = watch_register(c, h, &w)) || (rc = watch_loop(c, h, &w)))
		return rc;
	for (int i = 0; i < w.n; i++)
		cogw_dev_unwatch(h, w.a.line, &objs[i], c->timeout_ms);
	return 0;
}

const ctl_cmd ctl_cmd_watch = {
	.name = "watch",
	.synopsis =
		"  watch LINE NODE [INDEX SUB [TYPE]]       device objects' values as they come\n",
	.help = "usage: cogwctl watch LINE NODE [INDEX SUB [TYPE]] [--interval MS] [--count N]\n"
		"                     [--duration S]\n"
		"\n"
		"Prints every value of object INDEX:SUB of node NODE (without INDEX SUB: of every\n"
		"object its mirrored TPDOs carry) that the daemon receives in the node's TPDOs, "
		"decoded by its CiA 301 type (the one its file gives, else\n"
		"TYPE, else an unsigned number of the mapped size), with a sequence number (a\n"
		"gap means values were lost). The node must have \"pdo\": \"auto\" and its TPDO\n"
		"must have fitted the daemon's free PDOs ('cogwctl pdo map LINE NODE').\n"
		"  --interval MS  at most one value per MS (the latest when it ends)\n"
		"  --count N      stop after N values\n"
		"  --duration S   stop after S seconds\n"
		"\n"
		"Examples:\n"
		"  cogwctl watch 0 5 6000 1\n"
		"  cogwctl watch 0 5 --json\n"
		"  cogwctl watch 0 5 6401 1 i16 --interval 100 --json\n",
	.run = run_watch,
};

/* ---- dev read / write ------------------------------------------------------------ */

static const char *via_text(uint8_t via)
{
	return via == MBX_DEV_VIA_PDO ? "pdo" : "sdo";
}

static int dev_read(ctl *c, cogw *h, const dev_args *a, uint32_t max_age)
{
	char ctx[96];
	mbx_dev_value v;
	uint8_t buf[1024];
	size_t len = 0;
	uint32_t abort = 0;
	context(a, "read", ctx, sizeof ctx);
	int rc = cogw_dev_read(h, a->line, &a->obj, max_age, &v, buf, sizeof buf, &len,
			       c->timeout_ms, &abort);
	if (rc < 0)
		return ctl_fail(c, rc, abort, ctx);
	const ctl_type *t = cogw_type_of(v.type);
	if (c->json) {
		cJSON *o = json_object_head(a);
		cJSON_AddStringToObject(o, "via", via_text(v.via));
		if (v.via == MBX_DEV_VIA_PDO) {
			cJSON_AddNumberToObject(o, "age_ms", v.age_ms);
			cJSON_AddNumberToObject(o, "seq", v.seq);
		}
		if (t)
			cJSON_AddStringToObject(o, "data_type", t->cia_name);
		ctl_value_json(o, t, buf, len);
		ctl_json_print(o);
		return 0;
	}
	char *text = ctl_value_text(t, buf, len);
	printf("%s", text ? text : "?");
	if (v.via == MBX_DEV_VIA_PDO)
		printf("  (%s, from the mirror, %" PRIu32 " ms old)\n", t ? t->cia_name : "?",
		       v.age_ms);
	else
		printf("  (%s, by SDO)\n", t ? t->cia_name : "?");
	free(text);
	return 0;
}

static int dev_write(ctl *c, cogw *h, const dev_args *a, const char *value)
{
	char ctx[96];
	uint8_t *data = NULL;
	size_t len = 0;
	uint32_t abort = 0;
	mbx_dev_write_resp resp;
	int rc = ctl_value_encode(c, a->type, value, &data, &len);
	if (rc)
		return rc;
	context(a, "write", ctx, sizeof ctx);
	rc = cogw_dev_write(h, a->line, &a->obj, data, len, &resp, c->timeout_ms, &abort);
	free(data);
	if (rc < 0)
		return ctl_fail(c, rc, abort, ctx);
	if (c->json) {
		cJSON *o = json_object_head(a);
		cJSON_AddStringToObject(o, "via", via_text(resp.via));
		if (resp.via == MBX_DEV_VIA_PDO) {
			cJSON_AddNumberToObject(o, "rpdo", resp.pdo);
			cJSON_AddNumberToObject(o, "cob_id", resp.cob_id);
			cJSON_AddBoolToObject(o, "held", resp.held);
		}
		ctl_json_print(o);
	} else if (resp.via == MBX_DEV_VIA_PDO) {
		printf("written by the node's RPDO %u (COB-ID %03" PRIX32 "h)%s\n", resp.pdo,
		       resp.cob_id,
		       resp.held ? ", held until every object of that RPDO has a value" : "");
	} else {
		printf("written by SDO\n");
	}
	return 0;
}

static int run_dev(ctl *c, int argc, char **argv)
{
	const char *pos[8], *max_age = NULL;
	int n_pos;
	bool sdo = false;
	ctl_opt opts[] = { { "--max-age", true, &max_age, NULL },
			   { "--sdo", false, NULL, &sdo },
			   { NULL, false, NULL, NULL } };
	int rc = ctl_parse(c, argc, argv, opts, pos, 8, &n_pos);
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_dev);
	if (n_pos < 1)
		return ctl_usage_error(c, "read or write?");
	bool write = !strcmp(pos[0], "write");
	if (!write && strcmp(pos[0], "read"))
		return ctl_usage_error(c, "unknown action '%s' (read, write)", pos[0]);
	c->what = write ? "dev write" : "dev read";
	if (write ? n_pos != 7 : (n_pos < 5 || n_pos > 6))
		return ctl_usage_error(c, write ? "expected LINE NODE INDEX SUB TYPE VALUE"
						: "expected LINE NODE INDEX SUB [TYPE]");
	dev_args a;
	if ((rc = parse_object(c, pos + 1, n_pos - 1, &a)))
		return rc;
	uint64_t age = 0;
	if (max_age && (write || ctl_arg_uint(c, max_age, "--max-age", UINT32_MAX, &age) < 0))
		return write ? ctl_usage_error(c, "--max-age is for read") : CTL_EXIT_USAGE;
	if (sdo)
		a.obj.flags |= MBX_DEV_SDO_ONLY;
	int ex = 0;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	return write ? dev_write(c, h, &a, pos[6]) : dev_read(c, h, &a, (uint32_t)age);
}

const ctl_cmd ctl_cmd_dev = {
	.name = "dev",
	.synopsis = "  dev read|write LINE NODE INDEX SUB [TYPE] [VALUE]\n"
		    "                                           a device object by PDO or SDO\n",
	.help = "usage: cogwctl dev read LINE NODE INDEX SUB [TYPE] [--max-age MS] [--sdo]\n"
		"       cogwctl dev write LINE NODE INDEX SUB TYPE VALUE [--sdo]\n"
		"\n"
		"An object of node NODE, the way the daemon finds best (docs/devices.md):\n"
		"  read   from the daemon's mirror of the node's TPDOs when the last value is at\n"
		"         most --max-age ms old (default: the line's read_max_age_ms), else by\n"
		"         SDO; the output says which and how old the value is\n"
		"  write  by the node's RPDO when the daemon produces it (pdo \"auto\"): the\n"
		"         frame goes once every object of that RPDO has been given a value\n"
		"         (until then the answer says \"held\"); else by SDO\n"
		"  --sdo  always by SDO\n"
		"TYPE and VALUE as for 'sdo'; without TYPE, read uses the type the node's file\n"
		"gives (else an unsigned number of the value's size).\n"
		"\n"
		"Examples:\n"
		"  cogwctl dev read 0 5 6000 1\n"
		"  cogwctl dev write 0 5 6200 1 u8 3\n",
	.run = run_dev,
};
