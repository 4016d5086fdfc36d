/* SPDX-License-Identifier: MIT */
/*
 * apps/common/config_gateway.c - the configuration's "gateway" section:
 * the CiA 302-7 routes (1F2Ch) and process image of every line, and the
 * PDO forwarding by device object (docs/config.md).
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "apps/common/config_read.h"
#include "apps/common/json_od.h"
#include "apps/common/json_util.h"
#include "gateway/convention.h"
#include "gateway/image.h"
#include "gateway/route.h"

static const char *const gateway_keys[] = { "routes", "process_image", "forward", "comment", NULL };

static const char *const route_keys[] = { "network", "line", "router", "comment", NULL };

static const char *const forward_keys[] = { "from", "to", "image", "comment", NULL };

static const char *const dev_ref_keys[] = { "line", "node", "index", "sub", "comment", NULL };

/* ---- CiA 302-7 gateway ------------------------------------------------------------ */

/* The gateway objects of one line, before its own "objects" and "values"
 * (which may override them): this line's network id (5F00h), 1F2Ch with
 * the routes to every line's network and gateway.routes, and the shared
 * process image (gateway.process_image, the same objects on every line). */
int cfg_gateway_objects(struct ctx *c, cogw_line_config *l)
{
	co_od_entry *e;
	int rc;

	rc = co_od_add_num(l->od, GW_OBJ_NETWORK_ID, 0, CO_T_UNSIGNED8, CO_ACC_CO, l->network_id,
			   &e);
	if (rc)
		return cfg_fail(c, "lines", "cannot add %04Xh (%s)", GW_OBJ_NETWORK_ID,
				strerror(-rc));
	for (unsigned n = GW_NET_MIN; n <= GW_NET_MAX; n++) {
		if (!c->route_default[n] || !(e = co_od_find(l->od, GW_OBJ_ROUTES, (uint8_t)n)))
			continue;
		co_od_entry_set_default_raw(e, c->route_default[n]);
		co_od_entry_reset(e);
	}
	if (c->process_image &&
	    (rc = json_od_add_objects(l->od, c->process_image, "gateway.process_image", c->msg,
				      sizeof(c->msg))))
		return rc;
	return 0;
}

/* B000h..BFFFh is one image for all lines: defined once, in gateway. */
int cfg_refuse_image_objects(struct ctx *c, const cJSON *objects, const char *path)
{
	const cJSON *it;
	size_t i = 0;

	cJSON_ArrayForEach(it, objects)
	{
		char p[JSON_PATH_MAX];
		const cJSON *v = cJSON_IsObject(it) ? json_util_get(it, "index") : NULL;
		uint16_t index;

		json_util_path_index(p, sizeof(p), path, i++);
		if (v && json_od_parse_index(v, p, &index, c->msg, sizeof(c->msg)) == 0 &&
		    gw_image_in_range(index))
			return cfg_fail(c, p,
					"%04Xh: B000h..BFFFh is the shared process image of all "
					"lines: define it in gateway.process_image",
					index);
	}
	return 0;
}

/* Check the process image objects: B000h..BFFFh, numeric, at most 8 bytes
 * (what a classic CAN PDO can carry), PDO-mappable. */
int cfg_check_image(struct ctx *c, const co_od *od)
{
	for (size_t i = 0; i < co_od_count(od); i++) {
		const co_od_entry *e = co_od_at(od, i);

		if (e->obj_code != CO_OBJ_VAR && e->sub == 0)
			continue; /* sub 0 of an ARRAY/RECORD: the count */
		if (!gw_image_in_range(e->index))
			return cfg_fail(c, "gateway.process_image", "%04Xh is outside B000h..BFFFh",
					e->index);
		if (co_type_is_variable((co_type)e->type) || e->size > 8)
			return cfg_fail(c, "gateway.process_image",
					"%04Xh:%02X: a %s cannot be forwarded by PDO "
					"(numeric types of at most 8 bytes)",
					e->index, e->sub, co_type_to_string((co_type)e->type));
		if (!(e->access & (CO_ACC_RPDO | CO_ACC_TPDO)))
			return cfg_fail(c, "gateway.process_image",
					"%04Xh:%02X is not PDO-mappable (set \"pdo\": true)",
					e->index, e->sub);
	}
	return 0;
}

/* Every line's network id, read ahead of the lines (validated again, with
 * its path, when the line itself is parsed). */
void cfg_scan_networks(struct ctx *c, const cJSON *lines)
{
	const cJSON *it;

	c->n_lines = 0;
	cJSON_ArrayForEach(it, lines)
	{
		const cJSON *v = cJSON_IsObject(it) ? json_util_get(it, "network_id") : NULL;
		uint16_t net = (uint16_t)(c->n_lines + 1);

		if (c->n_lines >= COGW_LINES_MAX)
			break;
		if (v && cJSON_IsNumber(v) && v->valuedouble >= GW_NET_MIN &&
		    v->valuedouble <= GW_NET_MAX)
			net = (uint16_t)v->valuedouble;
		c->line_net[c->n_lines++] = net;
	}
	memset(c->route_default, 0, sizeof(c->route_default));
	for (size_t i = 0; i < c->n_lines; i++)
		c->route_default[c->line_net[i]] = gw_route_entry_encode(
			(gw_route_entry){ true, (uint8_t)i, 0 });
}

/* "values" for 1F2Ch:n go through the check of a run-time write (SDO or
 * mailbox, gateway/route.h gw_route_write_check): bits 16..31 set or a
 * line that does not exist are refused when the file is loaded, not left
 * to be silently no route. */
static uint32_t config_route_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	const struct ctx *c = ctx;
	(void)e;
	return gw_route_write_check(a, (uint8_t)c->n_lines);
}

static const co_od_hooks config_route_hooks = { .check_write = config_route_check };

void cfg_route_checks(struct ctx *c, co_od *od, bool on)
{
	for (unsigned n = GW_NET_MIN; n <= GW_NET_MAX; n++)
		(void)co_od_set_hooks(od, GW_OBJ_ROUTES, (uint8_t)n,
				      on ? &config_route_hooks : NULL, on ? c : NULL);
}

/* A network attached to one of our lines has one route, to that line: a
 * "values" entry that sends it elsewhere is a second route for it. */
int cfg_check_attached_routes(struct ctx *c, const char *path, const co_od *od)
{
	for (size_t i = 0; i < c->n_lines; i++) {
		uint16_t net = c->line_net[i];
		const co_od_entry *e = co_od_find(od, GW_OBJ_ROUTES, (uint8_t)net);
		uint32_t v = e ? (uint32_t)co_od_entry_raw(e) : 0;
		char p[JSON_PATH_MAX];

		if (!v || v == c->route_default[net])
			continue;
		json_util_path_key(p, sizeof(p), path, "values");
		return cfg_fail(c, p,
				"0x%04X:%02X = 0x%08X: network %u is attached to lines[%zu], its "
				"only route",
				GW_OBJ_ROUTES, net, v, net, i);
	}
	return 0;
}

static int parse_route(struct ctx *c, const cJSON *o, size_t idx)
{
	char path[JSON_PATH_MAX], pn[JSON_PATH_MAX], pl[JSON_PATH_MAX], pr[JSON_PATH_MAX];
	uint64_t net, line, router = 0;
	const cJSON *v;
	int rc;
	const json_at at = cfg_at(c, path);
	const json_at at_pn = cfg_at(c, pn);
	const json_at at_pl = cfg_at(c, pl);
	const json_at at_pr = cfg_at(c, pr);

	json_util_path_index(path, sizeof(path), "gateway.routes", idx);
	json_util_path_key(pn, sizeof(pn), path, "network");
	json_util_path_key(pl, sizeof(pl), path, "line");
	json_util_path_key(pr, sizeof(pr), path, "router");
	if ((rc = cfg_check_object(c, o, path, route_keys)))
		return rc;
	if ((rc = json_util_require(o, "network", &at, &v)) ||
	    (rc = json_util_uint(v, &at_pn, GW_NET_MIN, GW_NET_MAX, false, &net)) ||
	    (rc = json_util_require(o, "line", &at, &v)) ||
	    (rc = json_util_uint(v, &at_pl, 0, COGW_LINES_MAX - 1, false, &line)))
		return rc;
	if (line >= c->n_lines)
		return cfg_fail(c, pl, "line %u does not exist (%zu lines)", (unsigned)line,
				c->n_lines);
	v = json_util_get(o, "router");
	if (v && (rc = json_util_uint(v, &at_pr, 1, 127, false, &router)))
		return rc;
	for (size_t i = 0; i < c->n_lines; i++)
		if (c->line_net[i] == net)
			return cfg_fail(c, path,
					"network %u is attached to lines[%zu]: it needs no route",
					(unsigned)net, i);
	if (!router)
		return cfg_fail(c, path, "network %u is not attached here: name its next router",
				(unsigned)net);
	if (c->route_seen[net])
		return cfg_fail(c, pn, "network %u has a route already (gateway.routes[%u])",
				(unsigned)net, c->route_seen[net] - 1);
	c->route_seen[net] = (uint16_t)(idx + 1);
	c->route_default[net] = gw_route_entry_encode(
		(gw_route_entry){ true, (uint8_t)line, (uint8_t)router });
	return 0;
}

int cfg_parse_gateway(struct ctx *c, const cJSON *o)
{
	const cJSON *v, *it;
	size_t i = 0;
	int rc;

	if ((rc = cfg_check_object(c, o, "gateway", gateway_keys)))
		return rc;
	v = json_util_get(o, "routes");
	if (v) {
		if (!cJSON_IsArray(v))
			return cfg_fail(c, "gateway.routes", "expected an array, got %s",
					json_util_kind(v));
		/* one route per network at most, networks 1..127 */
		if (cJSON_GetArraySize(v) > (int)GW_NET_MAX)
			return cfg_fail(c, "gateway.routes",
					"%d routes, at most %u (one per network)",
					cJSON_GetArraySize(v), GW_NET_MAX);
		cJSON_ArrayForEach(it, v)
		{
			if ((rc = parse_route(c, it, i++)))
				return rc;
		}
	}
	v = json_util_get(o, "process_image");
	if (v) {
		co_od *od;

		/* Try the definitions once on their own, for errors that name
		 * gateway.process_image rather than a line. */
		if ((rc = co_od_create(&od, 16)))
			return rc;
		rc = json_od_add_objects(od, v, "gateway.process_image", c->msg, sizeof(c->msg));
		if (!rc)
			rc = cfg_check_image(c, od);
		co_od_destroy(od);
		if (rc)
			return rc;
		c->process_image = v;
	}
	return 0;
}

/* ---- PDO forwarding by device object ---------------------------------------------- */

/* One end of gateway.forward[i]: a node of that line mirrored by the device
 * object layer ("pdo": "auto"), whose PDO carries the object. */
static int parse_dev_ref(struct ctx *c, const cJSON *o, const char *path, const cogw_config *cfg,
			 cogw_dev_ref *r)
{
	char p[JSON_PATH_MAX];
	const cJSON *v;
	uint64_t x;
	int rc;
	const json_at at = cfg_at(c, path);
	const json_at at_p = cfg_at(c, p);

	if ((rc = cfg_check_object(c, o, path, dev_ref_keys)))
		return rc;
	json_util_path_key(p, sizeof(p), path, "line");
	if ((rc = json_util_require(o, "line", &at, &v)) ||
	    (rc = json_util_uint(v, &at_p, 0, cfg->n_lines - 1, false, &x)))
		return rc;
	r->line = (uint8_t)x;
	json_util_path_key(p, sizeof(p), path, "node");
	if ((rc = json_util_require(o, "node", &at, &v)) ||
	    (rc = json_util_uint(v, &at_p, 1, 127, false, &x)))
		return rc;
	r->node = (uint8_t)x;
	json_util_path_key(p, sizeof(p), path, "index");
	if ((rc = json_util_require(o, "index", &at, &v)) ||
	    (rc = json_od_parse_index(v, p, &r->index, c->msg, sizeof(c->msg))))
		return rc;
	json_util_path_key(p, sizeof(p), path, "sub");
	x = 0;
	if ((v = json_util_get(o, "sub")) && (rc = json_util_uint(v, &at_p, 0, 255, false, &x)))
		return rc;
	r->sub = (uint8_t)x;
	const cogw_line_config *l = &cfg->lines[r->line];
	for (size_t i = 0; i < l->n_nodes; i++)
		if (l->nodes[i].id == r->node) {
			if (l->nodes[i].pdo == COGW_PDO_AUTO)
				return 0;
			break;
		}
	return cfg_fail(c, path,
			"node %u of line %u is not mirrored: forwarding needs it in that line's "
			"\"nodes\" with \"pdo\": \"auto\" (docs/gateway.md)",
			r->node, r->line);
}

/* gateway.forward, once the lines are built: each entry's image object
 * (UNSIGNED64, PDO-mappable) goes into every line's OD, like
 * gateway.process_image. */
int cfg_parse_forwards(struct ctx *c, const cJSON *list, cogw_config *cfg)
{
	const cJSON *it;
	size_t i = 0;
	int rc;

	if (!cJSON_IsArray(list))
		return cfg_fail(c, "gateway.forward", "expected an array, got %s",
				json_util_kind(list));
	if (cJSON_GetArraySize(list) > (int)COGW_FORWARDS_MAX)
		return cfg_fail(c, "gateway.forward", "%d entries, at most %u",
				cJSON_GetArraySize(list), COGW_FORWARDS_MAX);
	cJSON_ArrayForEach(it, list)
	{
		char p[JSON_PATH_MAX], q[JSON_PATH_MAX];
		const json_at at = cfg_at(c, p);
		cogw_forward *f = &cfg->forwards[i];
		const cJSON *v;

		json_util_path_index(p, sizeof(p), "gateway.forward", i);
		if ((rc = cfg_check_object(c, it, p, forward_keys)))
			return rc;
		json_util_path_key(q, sizeof(q), p, "from");
		if ((rc = json_util_require(it, "from", &at, &v)) ||
		    (rc = parse_dev_ref(c, v, q, cfg, &f->from)))
			return rc;
		json_util_path_key(q, sizeof(q), p, "to");
		if ((rc = json_util_require(it, "to", &at, &v)) ||
		    (rc = parse_dev_ref(c, v, q, cfg, &f->to)))
			return rc;
		if (f->from.line == f->to.line)
			return cfg_fail(c, p,
					"from and to are on line %u: forwarding is between lines",
					f->from.line);
		f->image = (uint16_t)(COGW_FORWARD_IMAGE_FIRST + i);
		json_util_path_key(q, sizeof(q), p, "image");
		if ((v = json_util_get(it, "image")) &&
		    (rc = json_od_parse_index(v, q, &f->image, c->msg, sizeof(c->msg))))
			return rc;
		if (!gw_image_in_range(f->image))
			return cfg_fail(c, q, "%04Xh is outside the process image B000h..BFFFh",
					f->image);
		if (co_od_has_index(cfg->lines[0].od, f->image))
			return cfg_fail(c, q,
					"%04Xh is already an object of the process image: give "
					"another \"image\"",
					f->image);
		for (size_t l = 0; l < cfg->n_lines; l++) {
			co_od_entry *e;
			rc = co_od_add_num(cfg->lines[l].od, f->image, 0, CO_T_UNSIGNED64,
					   CO_ACC_RW | CO_ACC_RPDO | CO_ACC_TPDO, 0, &e);
			if (rc)
				return cfg_fail(c, q, "cannot add %04Xh (%s)", f->image,
						strerror(-rc));
		}
		i++;
		cfg->n_forwards = i;
	}
	return 0;
}
