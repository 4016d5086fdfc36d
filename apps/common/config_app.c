/* SPDX-License-Identifier: MIT */
/*
 * apps/common/config_app.c - a line's "app": the objects of its own node
 * that clients may own, and the bounds of what clients may create and
 * keep open (docs/config.md "Objects clients own", docs/application.md).
 * The objects themselves are defined in the line's "objects" (type,
 * access, PDO mapping, default); "app" names who owns them and how.
 */
#include "apps/common/config_read.h"

#include <string.h>

#include "apps/common/json_od.h"
#include "apps/common/json_util.h"
#include "mailbox/proto.h"

static const char *const app_keys[] = { "max_created", "max_per_client", "indications",
					"objects",     "comment",        NULL };
static const char *const decl_keys[] = { "index", "sub", "kind", "user", "uid", "comment", NULL };

static int parse_kind(struct ctx *c, const cJSON *o, const char *path, uint8_t *kind)
{
	char p[JSON_PATH_MAX], word[16];
	const cJSON *v;
	const json_at at_path = cfg_at(c, path), at = cfg_at(c, p);
	int rc;

	if ((rc = json_util_require(o, "kind", &at_path, &v)))
		return rc;
	json_util_path_key(p, sizeof(p), path, "kind");
	if ((rc = json_util_string(v, &at, 1, word, sizeof(word))))
		return rc;
	if (!strcmp(word, "held"))
		*kind = MBX_APP_HELD;
	else if (!strcmp(word, "served"))
		*kind = MBX_APP_SERVED;
	else
		return cfg_fail(c, p, "unknown kind \"%s\" (held or served)", word);
	return 0;
}

/* One declared object: it exists, it is an application object, and a
 * served one maps into no PDO (no PDO can wait for its owner). */
static int parse_decl(struct ctx *c, const cJSON *o, const char *path, cogw_line_config *l,
		      cogw_app_decl *d)
{
	char p[JSON_PATH_MAX];
	const cJSON *v;
	const json_at at_path = cfg_at(c, path), at = cfg_at(c, p);
	uint64_t sub = 0;
	int rc;

	if ((rc = cfg_check_object(c, o, path, decl_keys)) ||
	    (rc = json_util_require(o, "index", &at_path, &v)))
		return rc;
	json_util_path_key(p, sizeof(p), path, "index");
	if ((rc = json_od_parse_index(v, p, &d->index, c->msg, sizeof(c->msg))))
		return rc;
	if (d->index < 0x2000 || d->index > 0x9FFF)
		return cfg_fail(c, p, "%04Xh: objects clients own are in 2000h..9FFFh", d->index);
	if ((v = json_util_get(o, "sub"))) {
		json_util_path_key(p, sizeof(p), path, "sub");
		if ((rc = json_util_uint(v, &at, 0, 255, false, &sub)))
			return rc;
	}
	d->sub = (uint8_t)sub;
	if ((rc = parse_kind(c, o, path, &d->kind)) || (rc = cfg_parse_uid(c, o, path, &d->uid)))
		return rc;
	const co_od_entry *e = co_od_find(l->od, d->index, d->sub);
	if (!e)
		return cfg_fail(c, path, "%04Xh:%u is not in the line's \"objects\"", d->index,
				d->sub);
	if (d->kind == MBX_APP_SERVED && (e->access & (CO_ACC_RPDO | CO_ACC_TPDO)))
		return cfg_fail(c, path, "%04Xh:%u: a served object cannot be PDO-mappable",
				d->index, d->sub);
	for (uint16_t i = 0; i < l->app.n_decl; i++)
		if (l->app.decl[i].index == d->index && l->app.decl[i].sub == d->sub)
			return cfg_fail(c, path, "%04Xh:%u declared twice", d->index, d->sub);
	return 0;
}

int cfg_parse_app(struct ctx *c, const cJSON *v, const char *path, cogw_line_config *l)
{
	char p[JSON_PATH_MAX];
	const cJSON *objs, *o;
	int rc;

	if ((rc = cfg_check_object(c, v, path, app_keys)) ||
	    (rc = cfg_opt_u16(c, v, "max_created", path, (cfg_range){ 1, 1000 },
			      &l->app.max_created)) ||
	    (rc = cfg_opt_u16(c, v, "max_per_client", path, (cfg_range){ 1, 1000 },
			      &l->app.max_per_client)) ||
	    (rc = cfg_opt_u16(c, v, "indications", path, (cfg_range){ 1, 32 },
			      &l->app.indications)))
		return rc;
	objs = json_util_get(v, "objects");
	if (!objs)
		return 0;
	json_util_path_key(p, sizeof(p), path, "objects");
	if (!cJSON_IsArray(objs))
		return cfg_fail(c, p, "must be an array");
	if (cJSON_GetArraySize(objs) > COGW_APP_DECL_MAX)
		return cfg_fail(c, p, "at most %d objects", COGW_APP_DECL_MAX);
	size_t i = 0;
	cJSON_ArrayForEach(o, objs)
	{
		char q[JSON_PATH_MAX];
		json_util_path_index(q, sizeof(q), p, i++);
		if ((rc = parse_decl(c, o, q, l, &l->app.decl[l->app.n_decl])))
			return rc;
		l->app.n_decl++;
	}
	return 0;
}
