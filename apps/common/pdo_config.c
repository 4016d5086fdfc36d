/* SPDX-License-Identifier: MIT */
/*
 * apps/common/pdo_config.c - the "pdo", "pdo_scan_max", "eds" and "types"
 * keys (the contract is in pdo_config.h).
 */
#include "apps/common/pdo_config.h"

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "apps/common/json_od.h"
#include "apps/common/json_util.h"

static const char *const pdo_mode_names[] = { "off", "learn", "auto" };

const char *cogw_pdo_mode_to_string(uint8_t mode)
{
	return mode < 3 ? pdo_mode_names[mode] : "?";
}

int cogw_pdo_mode_parse(const cJSON *o, const char *path, uint8_t *mode, char *err, size_t errlen)
{
	char what[16], p[JSON_PATH_MAX];
	int rc;
	const json_at at = { path, err, errlen };

	snprintf(what, sizeof what, "%s", cogw_pdo_mode_to_string(*mode));
	if ((rc = json_util_opt_string(o, "pdo", &at, 1, what, sizeof what)))
		return rc;
	for (uint8_t m = 0; m < 3; m++)
		if (!strcmp(what, pdo_mode_names[m])) {
			*mode = m;
			return 0;
		}
	json_util_path_key(p, sizeof p, path, "pdo");
	return json_util_fail(err, errlen, p,
			      "\"%s\": expected \"off\", \"learn\" (learn the slaves' PDO "
			      "layouts) or \"auto\" (learn and mirror them)",
			      what);
}

/* The hex digits p..end (1 to 4 of them) as an index. */
static bool hex_index(const char *p, const char *end, uint16_t *index)
{
	unsigned long v = 0;

	for (const char *q = p; q < end; q++) {
		if (!isxdigit((unsigned char)*q))
			return false;
		v = v * 16 + (unsigned long)(isdigit((unsigned char)*q)
						     ? *q - '0'
						     : (tolower((unsigned char)*q) - 'a' + 10));
	}
	*index = (uint16_t)v;
	return true;
}

/* "6401:1", "0x6401:0x01", "6401h:1": the index is hex as CANopen writes
 * it, the sub-index decimal or 0x hex (as cogwctl takes them). */
static bool parse_object_key(const char *s, uint16_t *index, uint8_t *sub)
{
	const char *colon = strchr(s, ':');
	const char *p = s, *end;
	char *e;
	size_t n;
	unsigned long v;

	if (!colon)
		return false;
	if (p[0] == '0' && (p[1] == 'x' || p[1] == 'X'))
		p += 2;
	end = colon;
	if (end > p && (end[-1] == 'h' || end[-1] == 'H'))
		end--;
	n = (size_t)(end - p);
	if (n < 1 || n > 4 || !hex_index(p, end, index))
		return false;
	p = colon + 1;
	if (!*p || !isxdigit((unsigned char)*p))
		return false;
	errno = 0;
	v = strtoul(p, &e, (p[0] == '0' && (p[1] == 'x' || p[1] == 'X')) ? 16 : 10);
	if (errno || *e || v > 255)
		return false;
	*sub = (uint8_t)v;
	return true;
}

/* "types": {"6401:1": "INTEGER16", ...} into a sorted list (malloc'd). */
static int parse_types(const cJSON *v, const char *path, co_pdo_layout_type **out, size_t *n_out,
		       char *err, size_t errlen)
{
	co_pdo_layout_type *list;
	const co_pdo_layout_type *dup;
	const cJSON *it;
	size_t n = 0;

	if (!cJSON_IsObject(v))
		return json_util_fail(err, errlen, path,
				      "expected an object {\"6401:1\": \"INTEGER16\", ...}, got %s",
				      json_util_kind(v));
	if ((size_t)cJSON_GetArraySize(v) > COGW_NODE_TYPES_MAX)
		return json_util_fail(err, errlen, path, "%d objects, at most %u",
				      cJSON_GetArraySize(v), COGW_NODE_TYPES_MAX);
	list = calloc((size_t)cJSON_GetArraySize(v) + 1, sizeof *list);
	if (!list)
		return -ENOMEM;
	cJSON_ArrayForEach(it, v)
	{
		char p[JSON_PATH_MAX], name[32];
		const json_at at = { p, err, errlen };
		co_type t;
		co_pdo_layout_type *e = &list[n];
		int rc;

		json_util_path_key(p, sizeof p, path, it->string);
		if (!strcmp(it->string, "comment"))
			continue;
		if (!parse_object_key(it->string, &e->index, &e->sub)) {
			free(list);
			return json_util_fail(err, errlen, p,
					      "not an object \"INDEX:SUB\" (index hex, e.g. "
					      "\"6401:1\")");
		}
		if ((rc = json_util_string(it, &at, 1, name, sizeof name))) {
			free(list);
			return rc;
		}
		if (!json_od_type_from_string(name, &t)) {
			free(list);
			return json_util_fail(err, errlen, p,
					      "\"%s\" is not a CiA 301 data type name (e.g. "
					      "\"INTEGER16\", \"REAL32\")",
					      name);
		}
		e->type = (uint16_t)t;
		n++;
	}
	if (!eds_pdo_types_sort(list, n, &dup)) {
		uint16_t index = dup->index;
		uint8_t sub = dup->sub;
		free(list);
		return json_util_fail(err, errlen, path, "object %04X:%u is named twice", index,
				      sub);
	}
	*out = list;
	*n_out = n;
	return 0;
}

/* The file's layout (when it is the node's) and types, the node's
 * "types" (r->overrides) over the file's, into n. */
static int finish_file(eds_pdo_reader *r, const char *p, const char *file, cogw_node *n,
		       const cogw_load *ld)
{
	char why[400];
	eds_pdo_types t = { 0 };
	int rc = eds_pdo_reader_finish(r, file, n->pdo_from_file ? &n->pdo_file : NULL, &t, why,
				       sizeof why);
	if (rc == -EINVAL)
		return json_util_fail(ld->err, ld->errlen, p, "%s", why);
	if (rc)
		return rc;
	n->types = t.list;
	n->n_types = t.n;
	return 0;
}

int cogw_node_pdo_parse(const cJSON *node, const char *np, const cogw_line_config *l, cogw_node *n,
			const cogw_load *ld)
{
	char *err = ld->err;
	size_t errlen = ld->errlen;
	const cJSON *cfg = json_util_get(node, "config"), *eds = json_util_get(node, "eds");
	const cJSON *types = json_util_get(node, "types");
	eds_pdo_types o = { 0 }; /* the node's "types" */
	eds_pdo_reader r = { 0 };
	char p[JSON_PATH_MAX], fp[JSON_PATH_MAX];
	int rc = 0;

	n->pdo = l->pdo;
	if ((rc = cogw_pdo_mode_parse(node, np, &n->pdo, err, errlen)))
		return rc;
	json_util_path_key(p, sizeof p, np, "types");
	if (types && (rc = parse_types(types, p, &o.list, &o.n, err, errlen)))
		return rc;
	if (cfg) {
		json_util_path_key(p, sizeof p, np, "config");
		rc = cogw_node_config_parse(cfg, p, (cogw_device_ref){ n->id, eds ? NULL : &r }, ld,
					    &n->config);
		json_util_path_key(fp, sizeof fp, p, "dcf");
	}
	if (!rc && eds && n->config.source == COGW_NODE_CONFIG_DCF) {
		json_util_path_key(p, sizeof p, np, "eds");
		rc = json_util_fail(err, errlen, p,
				    "node %u has \"config\": {\"dcf\": ...} too, which describes "
				    "the configured device: give one of them",
				    n->id);
	} else if (!rc && eds) {
		json_util_path_key(fp, sizeof fp, np, "eds");
		rc = cogw_device_file_read(eds, fp, (cogw_device_ref){ n->id, &r }, ld, n->eds);
	}
	if (!rc && (eds || n->config.source == COGW_NODE_CONFIG_DCF)) {
		/* with "eds" and a download of another kind the download may
		 * remap: the file then only types what the scan finds */
		n->pdo_from_file = !(eds && cfg);
		r.overrides = o;
		rc = finish_file(&r, fp, eds ? n->eds : n->config.file, n, ld);
	} else if (!rc) {
		n->types = o.list;
		n->n_types = o.n;
		o.list = NULL;
	}
	free(o.list);
	eds_pdo_reader_free(&r);
	return rc;
}

void cogw_node_pdo_free(cogw_node *n)
{
	eds_pdo_file_free(&n->pdo_file);
	free(n->types);
	n->types = NULL;
	n->n_types = 0;
}

bool cogw_node_pdo_equal(const cogw_node *a, const cogw_node *b)
{
	if (a->pdo != b->pdo || strcmp(a->eds, b->eds) || a->pdo_from_file != b->pdo_from_file ||
	    a->n_types != b->n_types ||
	    (a->n_types && memcmp(a->types, b->types, a->n_types * sizeof *a->types)))
		return false;
	for (unsigned d = 0; d < 2; d++)
		if (a->pdo_file.n[d] != b->pdo_file.n[d] ||
		    (a->pdo_file.n[d] && memcmp(a->pdo_file.pdo[d], b->pdo_file.pdo[d],
						a->pdo_file.n[d] * sizeof *a->pdo_file.pdo[d])))
			return false;
	return true;
}

bool cogw_node_pdo_scanned(const cogw_node *n)
{
	return n->pdo != COGW_PDO_OFF && !n->pdo_from_file;
}

bool cogw_node_pdo_kept(const cogw_node *n)
{
	return n->pdo_from_file || cogw_node_pdo_scanned(n);
}

int cogw_line_pdo_check(const cogw_line_config *l, const char *path, char *err, size_t errlen)
{
	char np[JSON_PATH_MAX], p[JSON_PATH_MAX];

	if (l->manager.enabled)
		return 0;
	for (size_t i = 0; i < l->n_nodes; i++) {
		if (!cogw_node_pdo_scanned(&l->nodes[i]))
			continue;
		json_util_path_key(np, sizeof np, path, "nodes");
		json_util_path_index(p, sizeof p, np, i);
		return json_util_fail(err, errlen, p,
				      "node %u learns its PDO layout by SDO (pdo \"%s\", no "
				      "config.dcf or eds), a step of the manager's boot: the line "
				      "has no \"manager\"",
				      l->nodes[i].id, cogw_pdo_mode_to_string(l->nodes[i].pdo));
	}
	return 0;
}
