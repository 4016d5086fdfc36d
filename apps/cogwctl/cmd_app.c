/* SPDX-License-Identifier: MIT */
/*
 * cogwctl app: the objects clients own on a line's own node
 * (docs/application.md): who owns which, held or served, and the
 * counters of their indications.
 */
#include <inttypes.h>
#include <string.h>

#include "apps/cogwctl/ctl.h"

#define APP_LIST_MAX 256

static const char *kind_name(uint8_t k)
{
	return k == MBX_APP_SERVED ? "served" : k == MBX_APP_HELD ? "held" : "?";
}

static void access_text(uint8_t a, char *buf)
{
	snprintf(buf, 8, "%s%s%s%s", a & MBX_APP_READ ? "r" : "", a & MBX_APP_WRITE ? "w" : "",
		 a & MBX_APP_TPDO ? "T" : "", a & MBX_APP_RPDO ? "R" : "");
}

static void counters_json(cJSON *o, const mbx_app_status *st)
{
	cJSON_AddNumberToObject(o, "max_objects", st->max_objects);
	cJSON_AddNumberToObject(o, "max_per_client", st->max_per_client);
	cJSON_AddNumberToObject(o, "max_indications_per_client", st->max_ind_per_client);
	cJSON_AddNumberToObject(o, "indications", st->ind_sent);
	cJSON_AddNumberToObject(o, "answered", st->ind_answered);
	cJSON_AddNumberToObject(o, "late", st->ind_late);
	cJSON_AddNumberToObject(o, "no_owner", st->ind_no_owner);
	cJSON_AddNumberToObject(o, "refused_busy", st->ind_refused_full);
	cJSON_AddNumberToObject(o, "cancelled", st->ind_cancelled);
	cJSON_AddNumberToObject(o, "answers_refused", st->answers_refused);
	cJSON_AddNumberToObject(o, "claims_refused", st->claims_refused);
	cJSON_AddNumberToObject(o, "written_events", st->written_events);
}

static void list_json(cJSON *arr, unsigned line, const mbx_app_status *st, const mbx_app_obj *objs,
		      size_t n)
{
	cJSON *o = cJSON_CreateObject();
	cJSON_AddNumberToObject(o, "line", line);
	counters_json(o, st);
	cJSON *list = cJSON_AddArrayToObject(o, "objects");
	for (size_t i = 0; i < n; i++) {
		char acc[8], idx[8];
		cJSON *e = cJSON_CreateObject();
		snprintf(idx, sizeof idx, "%04X", objs[i].index);
		cJSON_AddStringToObject(e, "index", idx);
		cJSON_AddNumberToObject(e, "sub", objs[i].sub);
		cJSON_AddStringToObject(e, "kind", kind_name(objs[i].kind));
		const cogw_type *t = cogw_type_of(objs[i].type);
		cJSON_AddStringToObject(e, "type", t ? t->cia_name : "?");
		access_text(objs[i].access, acc);
		cJSON_AddStringToObject(e, "access", acc);
		cJSON_AddBoolToObject(e, "declared", objs[i].declared);
		cJSON_AddNumberToObject(e, "owner", objs[i].owner);
		cJSON_AddNumberToObject(e, "uid", objs[i].uid);
		cJSON_AddNumberToObject(e, "open", objs[i].open);
		cJSON_AddItemToArray(list, e);
	}
	cJSON_AddItemToArray(arr, o);
}

static void list_text(unsigned line, const mbx_app_status *st, const mbx_app_obj *objs, size_t n)
{
	printf("line %u: %u object%s clients may own (bound %u), indications %" PRIu32
	       " (answered %" PRIu32 ", late %" PRIu32 ", no owner %" PRIu32 ", busy %" PRIu32
	       ", cancelled %" PRIu32 "), answers refused %" PRIu32 ", claims refused %" PRIu32
	       "\n",
	       line, st->n, st->n == 1 ? "" : "s", st->max_objects, st->ind_sent, st->ind_answered,
	       st->ind_late, st->ind_no_owner, st->ind_refused_full, st->ind_cancelled,
	       st->answers_refused, st->claims_refused);
	if (n)
		printf("  %-9s  %-6s  %-14s  %-6s  %-8s  %-8s  %s\n", "object", "kind", "type",
		       "access", "from", "owner", "open");
	for (size_t i = 0; i < n; i++) {
		char acc[8], owner[16];
		const cogw_type *t = cogw_type_of(objs[i].type);
		access_text(objs[i].access, acc);
		if (objs[i].owner)
			snprintf(owner, sizeof owner, "%" PRIu32, objs[i].owner);
		else
			snprintf(owner, sizeof owner, "-");
		printf("  %04X:%-4u  %-6s  %-14s  %-6s  %-8s  %-8s  %" PRIu32 "\n", objs[i].index,
		       objs[i].sub, kind_name(objs[i].kind), t ? t->cia_name : "?", acc,
		       objs[i].declared ? "config" : "client", owner, objs[i].open);
	}
}

static int show(ctl *c, cogw *h, unsigned line, cJSON *arr)
{
	static mbx_app_obj objs[APP_LIST_MAX];
	mbx_app_status st;
	size_t n = 0;
	char ctx[48];
	snprintf(ctx, sizeof ctx, "application objects of line %u", line);
	int rc = cogw_app_list(h, line, &st, objs, APP_LIST_MAX, &n, c->timeout_ms);
	if (rc < 0 && rc != COGW_E_TRUNCATED)
		return ctl_fail(c, rc, 0, ctx);
	if (arr)
		list_json(arr, line, &st, objs, n);
	else
		list_text(line, &st, objs, n);
	return 0;
}

static int run(ctl *c, int argc, char **argv)
{
	return ctl_run_lines(c, argc, argv, &ctl_cmd_app, show);
}

const ctl_cmd ctl_cmd_app = {
	.name = "app",
	.synopsis = "  app [LINE...]                           objects clients own, indications\n",
	.help = "usage: cogwctl app [LINE...]\n"
		"\n"
		"The objects of the daemon's own node that clients own on every line (or the\n"
		"lines given), docs/application.md: index and sub-index, held (the daemon\n"
		"keeps the value) or served (every access goes to the owner), type, access\n"
		"(r, w, T = TPDO-mappable, R = RPDO-mappable), declared in the configuration\n"
		"or created by a client, the owner's client id (- = none: accesses answer\n"
		"08000021h) and the indications open on it; then the line's counters:\n"
		"indications handed to owners, answered, answered by the line because the\n"
		"owner was late (08000020h), had gone (08000021h) or had too many open\n"
		"(060A0023h), cancelled by their requester, answers and claims refused.\n"
		"\n"
		"Examples:\n"
		"  cogwctl app\n"
		"  cogwctl app 0 --json\n",
	.run = run,
};
