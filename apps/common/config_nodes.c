/* SPDX-License-Identifier: MIT */
/*
 * apps/common/config_nodes.c - a line's "nodes" and "manager" sections:
 * the slaves the CiA 302 manager boots, their downloads, programs and
 * states, and the manager's own objects (1F80h, 1F81h, ...).
 */
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "apps/common/config_read.h"
#include "apps/common/json_od.h"
#include "apps/common/json_util.h"
#include "apps/common/pdo_config.h"
#include "core/cfgmgr.h"
#include "core/manager.h"
#include "core/nmt.h"
#include "core/swmgr.h"

static const char *const node_keys[] = { "id",
					 "config",
					 "mandatory",
					 "boot",
					 "keep_alive",
					 "retry_factor",
					 "guard_time_ms",
					 "heartbeat_ms",
					 "device_type",
					 "vendor_id",
					 "product_code",
					 "revision",
					 "serial",
					 "keep_op",
					 "state",
					 "software_id",
					 "software_update",
					 "program",
					 "pdo",
					 "eds",
					 "types",
					 "comment",
					 NULL };

static const char *const manager_keys[] = { "master",
					    "start_all",
					    "self_start",
					    "start_slaves",
					    "on_mandatory_error",
					    "boot_time_ms",
					    "retry_ms",
					    "scan_ms",
					    "reset_wait_ms",
					    "sdo_timeout_ms",
					    "max_parallel",
					    "accept_remote_nmt",
					    "comment",
					    NULL };

/* The image file of "program", read whole now (start-up: the line thread
 * later reads it from memory), once for all nodes that name it. */
static int load_program(struct ctx *c, const char *p, const char *name, cogw_node *n)
{
	char why[512];
	int rc;

	if (name[0] == '/' || !c->base_dir[0])
		snprintf(n->program_file, sizeof(n->program_file), "%s", name);
	else if ((size_t)snprintf(n->program_file, sizeof(n->program_file), "%s/%s", c->base_dir,
				  name) >= sizeof(n->program_file))
		return cfg_fail(c, p, "file name too long");
	cogw_file_bytes image;
	rc = cogw_file_set_get(c->read, n->program_file, COGW_PROGRAM_MAX, &image, why,
			       sizeof(why));
	if (rc == -ENOMEM)
		return rc;
	if (rc)
		return cfg_fail(c, p, "%s", why);
	n->program = image.data;
	n->program_len = image.len;
	if (!n->program_len) {
		n->program = NULL;
		return cfg_fail(c, p, "%s: a program image of 1..%u bytes, not 0", n->program_file,
				COGW_PROGRAM_MAX);
	}
	return 0;
}

/* The CiA 302-3 software manager settings of a node: "software_id"
 * (1F55h:n, sets 1F81h:n bit 5), "software_update" with "program" (the
 * image of 1F58h:n; sets bit 6). */
static int parse_node_software(struct ctx *c, const cJSON *it, const char *np, cogw_node *n,
			       uint32_t *a)
{
	const cJSON *prog = json_util_get(it, "program");
	char p[JSON_PATH_MAX], name[256];
	bool update = false;
	int rc;
	const json_at at = cfg_at(c, np);
	const json_at at_p = cfg_at(c, p);

	if ((rc = cfg_opt_u32_hex(c, it, "software_id", np, &n->software_id)) ||
	    (rc = json_util_opt_bool(it, "software_update", &at, &update)))
		return rc;
	if (n->software_id)
		*a |= CO_SWMGR_F81_CHECK;
	if (!update && !prog)
		return 0;
	json_util_path_key(p, sizeof(p), np, update ? "software_update" : "program");
	if (!update || !prog || !n->software_id)
		return cfg_fail(c, p,
				"\"software_update\": true, \"program\" and a non-zero "
				"\"software_id\" go together (node %u)",
				n->id);
	*a |= CO_SWMGR_F81_UPDATE;
	json_util_path_key(p, sizeof(p), np, "program");
	if ((rc = json_util_string(prog, &at_p, 1, name, sizeof(name))))
		return rc;
	return load_program(c, p, name, n);
}

/* "state": the NMT state the manager puts the node in after its boot. */
static int parse_node_state(struct ctx *c, const cJSON *it, const char *np, uint8_t *state)
{
	static const struct {
		const char *name;
		uint8_t nmt;
	} names[] = { { "operational", CO_NMT_OPERATIONAL },
		      { "pre-operational", CO_NMT_PRE_OPERATIONAL },
		      { "stopped", CO_NMT_STOPPED } };
	char what[20] = "operational", p[JSON_PATH_MAX];
	int rc;
	const json_at at = cfg_at(c, np);

	if ((rc = json_util_opt_string(it, "state", &at, 1, what, sizeof(what))))
		return rc;
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++)
		if (!strcmp(what, names[i].name)) {
			*state = names[i].nmt;
			return 0;
		}
	json_util_path_key(p, sizeof(p), np, "state");
	return cfg_fail(
		c, p, "\"%s\": expected \"operational\", \"pre-operational\" or \"stopped\"", what);
}

/* The CiA 302-2 settings of one entry of "nodes" (1F81h:n, 1F84h..1F88h:n,
 * the 1016h consumer time, KEEP_OP). */
static int parse_node_manager(struct ctx *c, const cJSON *it, const char *np, cogw_node *n)
{
	static const char *const id_keys[5] = { "device_type", "vendor_id", "product_code",
						"revision", "serial" };
	uint32_t a = CO_MGR_1F81_SLAVE, factor = 0, guard = 0;
	uint16_t hb = 0;
	bool keep_op = false;
	int rc;
	const json_at at = cfg_at(c, np);

	if ((rc = cfg_opt_flag(c, it, "boot", np, (cfg_flag){ CO_MGR_1F81_BOOT, true }, &a)) ||
	    (rc = cfg_opt_flag(c, it, "mandatory", np, (cfg_flag){ CO_MGR_1F81_MANDATORY, false },
			       &a)) ||
	    (rc = cfg_opt_flag(c, it, "keep_alive", np, (cfg_flag){ CO_MGR_1F81_KEEP_ALIVE, false },
			       &a)) ||
	    (rc = cfg_opt_u32(c, it, "retry_factor", np, (cfg_range){ 0, 255 }, &factor)) ||
	    (rc = cfg_opt_u32(c, it, "guard_time_ms", np, (cfg_range){ 0, 65535 }, &guard)) ||
	    (rc = cfg_opt_u16(c, it, "heartbeat_ms", np, (cfg_range){ 0, 65535 }, &hb)) ||
	    (rc = json_util_opt_bool(it, "keep_op", &at, &keep_op)))
		return rc;
	for (int i = 0; i < 5; i++)
		if ((rc = cfg_opt_u32_hex(c, it, id_keys[i], np, &n->identity[i])))
			return rc;
	if (hb && guard) {
		char p[JSON_PATH_MAX];
		json_util_path_key(p, sizeof(p), np, "guard_time_ms");
		return cfg_fail(c, p, "node %u has heartbeat_ms too: supervise it one way", n->id);
	}
	if ((rc = parse_node_software(c, it, np, n, &a)) ||
	    (rc = parse_node_state(c, it, np, &n->target_state)))
		return rc;
	n->assignment = a | factor << 8 | guard << 16;
	n->heartbeat_ms = hb;
	n->keep_op = keep_op;
	return 0;
}

/* The manager's NMT start-up (1F80h) from its flags and
 * "on_mandatory_error". */
static int parse_nmt_startup(struct ctx *c, const cJSON *o, const char *path, uint32_t *bits)
{
	char p[JSON_PATH_MAX], what[16] = "node";
	uint32_t b = 0, self = 0, slaves = 0;
	int rc;
	const json_at at = cfg_at(c, path);

	if ((rc = cfg_opt_flag(c, o, "master", path, (cfg_flag){ CO_MGR_1F80_MASTER, true }, &b)) ||
	    (rc = cfg_opt_flag(c, o, "start_all", path, (cfg_flag){ CO_MGR_1F80_START_ALL, false },
			       &b)))
		return rc;
	/* bits 2 and 3 say what the manager may NOT do: the names say what it
	 * does */
	if ((rc = cfg_opt_flag(c, o, "self_start", path, (cfg_flag){ 1, true }, &self)) ||
	    (rc = cfg_opt_flag(c, o, "start_slaves", path, (cfg_flag){ 1, true }, &slaves)))
		return rc;
	if (!self)
		b |= CO_MGR_1F80_NO_SELF_START;
	if (!slaves)
		b |= CO_MGR_1F80_APP_STARTS_SLAVES;
	if ((rc = json_util_opt_string(o, "on_mandatory_error", &at, 1, what, sizeof(what))))
		return rc;
	json_util_path_key(p, sizeof(p), path, "on_mandatory_error");
	if (!strcmp(what, "reset_all"))
		b |= CO_MGR_1F80_RESET_ALL_ON_ERROR;
	else if (!strcmp(what, "stop_all"))
		b |= CO_MGR_1F80_STOP_ALL_ON_ERROR;
	else if (strcmp(what, "node"))
		return cfg_fail(c, p, "\"%s\": expected \"node\", \"reset_all\" or \"stop_all\"",
				what);
	*bits = b;
	return 0;
}

/* "manager": the line's CiA 302-2 manager; 1F80h from names. */
int cfg_parse_manager(struct ctx *c, const cJSON *o, const char *path, cogw_manager_config *m)
{
	int rc;
	const json_at at = cfg_at(c, path);

	if ((rc = cfg_check_object(c, o, path, manager_keys)))
		return rc;
	m->enabled = true;
	m->retry_ms = 1000;
	m->reset_wait_ms = 1000;
	m->sdo_timeout_ms = 500;
	m->boot_time_ms = 0;
	if ((rc = parse_nmt_startup(c, o, path, &m->nmt_startup)) ||
	    (rc = cfg_opt_u32(c, o, "boot_time_ms", path, (cfg_range){ 0, 3600000 },
			      &m->boot_time_ms)) ||
	    (rc = cfg_opt_u32(c, o, "retry_ms", path, (cfg_range){ 10, 3600000 }, &m->retry_ms)) ||
	    (rc = cfg_opt_u32(c, o, "scan_ms", path, (cfg_range){ 0, 3600000 }, &m->scan_ms)) ||
	    (rc = cfg_opt_u32(c, o, "reset_wait_ms", path, (cfg_range){ 1, 60000 },
			      &m->reset_wait_ms)) ||
	    (rc = cfg_opt_u32(c, o, "sdo_timeout_ms", path, (cfg_range){ 1, 60000 },
			      &m->sdo_timeout_ms)) ||
	    (rc = cfg_opt_u8(c, o, "max_parallel", path, (cfg_range){ 0, 128 },
			     &m->max_parallel)) ||
	    (rc = json_util_opt_bool(o, "accept_remote_nmt", &at, &m->accept_remote_nmt)))
		return rc;
	return 0;
}

/* The manager's objects in the line's OD, as defaults (a reset
 * communication keeps them): 1F80h, 1F89h, 1F81h:n, 1F84h..1F88h:n and a
 * 1016h entry per node with heartbeat_ms. */
static int set_default(co_od *od, uint16_t index, uint8_t sub, uint32_t v)
{
	co_od_entry *e = co_od_find(od, index, sub);
	if (!e)
		return -ENOENT;
	co_od_entry_set_default_raw(e, v);
	co_od_entry_reset(e);
	return 0;
}

/* Node i's heartbeat (heartbeat_ms) consumed in a free sub of 1016h. */
static int consume_heartbeat(struct ctx *c, const char *path, cogw_line_config *l, size_t i)
{
	const cogw_node *n = &l->nodes[i];
	uint8_t free_sub = 0, subs = 0;
	int rc;

	(void)co_od_get_u8(l->od, 0x1016, 0, &subs);
	for (unsigned s = 1; s <= subs; s++) {
		uint32_t v = 0;
		(void)co_od_get_u32(l->od, 0x1016, (uint8_t)s, &v);
		if (((v >> 16) & 0xFF) == n->id && (v & 0xFFFF)) {
			char np[JSON_PATH_MAX], pp[JSON_PATH_MAX];
			json_util_path_key(np, sizeof(np), path, "nodes");
			json_util_path_index(pp, sizeof(pp), np, i);
			json_util_path_key(np, sizeof(np), pp, "heartbeat_ms");
			return cfg_fail(c, np, "node %u is in heartbeat_consumers too", n->id);
		}
		if (!free_sub && !v)
			free_sub = (uint8_t)s;
	}
	if (!free_sub)
		return cfg_fail(c, path, "1016h is full");
	if ((rc = set_default(l->od, 0x1016, free_sub, (uint32_t)n->id << 16 | n->heartbeat_ms)))
		return cfg_fail(c, path, "1016h:%u: %s", free_sub, strerror(-rc));
	return 0;
}

/* Node n's 1F81h, 1F84h..1F88h and 1F55h. */
static int node_manager_objects(struct ctx *c, const char *path, co_od *od, const cogw_node *n)
{
	int rc;

	if ((rc = set_default(od, 0x1F81, n->id, n->assignment)))
		return cfg_fail(c, path, "1F81h:%u: %s", n->id, strerror(-rc));
	for (int k = 0; k < 5; k++)
		if ((rc = set_default(od, (uint16_t)(0x1F84 + k), n->id, n->identity[k])))
			return cfg_fail(c, path, "%04Xh:%u: %s", 0x1F84 + k, n->id, strerror(-rc));
	if (n->software_id &&
	    ((rc = co_od_add_swmgr_defaults(od)) ||
	     (rc = set_default(od, CO_SWMGR_IDX_EXPECTED, n->id, n->software_id))))
		return cfg_fail(c, path, "1F55h:%u: %s", n->id, strerror(-rc));
	return 0;
}

int cfg_manager_objects(struct ctx *c, const char *path, cogw_line_config *l)
{
	const cogw_manager_config *m = &l->manager;
	int rc;

	if (!m->enabled)
		return 0;
	if ((rc = co_od_add_manager_defaults(l->od, m->nmt_startup)) < 0)
		return rc == -ENOMEM ? rc
				     : cfg_fail(c, path, "cannot add the manager objects (%s)",
						strerror(-rc));
	if ((rc = set_default(l->od, 0x1F80, 0, m->nmt_startup)) ||
	    (rc = set_default(l->od, 0x1F89, 0, m->boot_time_ms)))
		return cfg_fail(c, path, "1F80h/1F89h: %s", strerror(-rc));
	for (size_t i = 0; i < l->n_nodes; i++) {
		if ((rc = node_manager_objects(c, path, l->od, &l->nodes[i])) ||
		    (l->nodes[i].heartbeat_ms && (rc = consume_heartbeat(c, path, l, i))))
			return rc;
	}
	return 0;
}

/* "nodes": [{"id": N, "config": {...}}]. Node configurations are loaded
 * (files read, DCFs converted) here, so a broken one stops the start. */
int cfg_parse_nodes(struct ctx *c, const cJSON *v, const char *path, cogw_line_config *l)
{
	const cJSON *it;
	size_t i = 0;
	int rc;

	if (!cJSON_IsArray(v))
		return cfg_fail(c, path, "expected an array of nodes, got %s", json_util_kind(v));
	if (cJSON_GetArraySize(v) > 127)
		return cfg_fail(c, path, "%d nodes, at most 127", cJSON_GetArraySize(v));
	l->nodes = calloc((size_t)cJSON_GetArraySize(v) + 1, sizeof(*l->nodes));
	if (!l->nodes)
		return -ENOMEM;
	cJSON_ArrayForEach(it, v)
	{
		char np[JSON_PATH_MAX], p[JSON_PATH_MAX];
		const json_at at = cfg_at(c, np), at_p = cfg_at(c, p);
		cogw_node *n = &l->nodes[i];
		const cJSON *x;
		uint64_t id;

		json_util_path_index(np, sizeof(np), path, i++);
		if ((rc = cfg_check_object(c, it, np, node_keys)) ||
		    (rc = json_util_require(it, "id", &at, &x)))
			return rc;
		json_util_path_key(p, sizeof(p), np, "id");
		if ((rc = json_util_uint(x, &at_p, 1, 127, false, &id)))
			return rc;
		if (id == l->node_id)
			return cfg_fail(c, p, "%llu is the line's own node_id",
					(unsigned long long)id);
		for (size_t j = 0; j < l->n_nodes; j++)
			if (l->nodes[j].id == id)
				return cfg_fail(c, p, "node %llu is already in %s[%zu]",
						(unsigned long long)id, path, j);
		n->id = (uint8_t)id;
		l->n_nodes++;
		if ((rc = parse_node_manager(c, it, np, n)) ||
		    (rc = cogw_node_pdo_parse(it, np, l, n,
					      &(cogw_load){ c->base_dir, c->files, c->read, c->msg,
							    sizeof(c->msg) })))
			return rc;
	}
	return 0;
}
