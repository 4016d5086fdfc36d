/* SPDX-License-Identifier: MIT */
/*
 * apps/common/config_line.c - one entry of the configuration's "lines":
 * its interface, identity, real-time settings, device objects and the
 * object dictionary built from them (docs/config.md).
 *
 * Order of a line's OD: the standard communication objects for its node id
 * (core/od_std.h) from the line's keys, then "objects", then "values". The
 * line's structured keys (heartbeat_ms, heartbeat_consumers,
 * sync_period_us) are read back from the OD at the end, so that a "values"
 * entry for 1016h/1017h/1006h and the struct never disagree.
 */
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
#include "core/nmt.h"
#include "core/od_std.h"
#include "mailbox/proto.h"

#define IFNAME_MAX 15u /* IFNAMSIZ - 1 */

static const char *const line_keys[] = { "name",           "interface",
					 "bitrate",        "node_id",
					 "network_id",     "rt",
					 "sdo_servers",    "sdo_clients",
					 "sdo_timeout_ms", "sdo_block_threshold",
					 "heartbeat_ms",   "sync_period_us",
					 "time_period_ms", "heartbeat_consumers",
					 "device",         "rpdos",
					 "tpdos",          "objects",
					 "values",         "nodes",
					 "manager",        "pdo",
					 "pdo_scan_max",   "device_objects",
					 "fault_quiet_ms", "id_conflict_quiet_ms",
					 "unknown_nodes",  "app",
					 "comment",        NULL };

static const char *const rt_keys[] = { "priority", "cpu", "comment", NULL };

static const char *const devobj_keys[] = { "read_max_age_ms", "write_update_ms", "watches",
					   "comment", NULL };

static const char *const hb_keys[] = { "node_id", "time_ms", "comment", NULL };

static const char *const device_keys[] = { "device_type", "name",      "hw_version",
					   "sw_version",  "vendor_id", "product_code",
					   "revision",    "serial",    "comment",
					   NULL };

/* CiA 301 §7.2.2 / CiA 102 bit timing table (10 kbit/s .. 1 Mbit/s). */
static const uint32_t cia_bitrates[] = { 10000,  20000,  50000,  125000,
					 250000, 500000, 800000, 1000000 };

/* ---- lines --------------------------------------------------------------------- */

/* The line's own device: its standard objects (1000h, 1008h..100Ah,
 * 1018h and the rest of core/od_std.h) and the strings they point to. */
struct line_device {
	co_od_std_opts so;
	char name[CO_OD_STD_STRING_MAX + 1];
	char hw[CO_OD_STD_STRING_MAX + 1];
	char sw[CO_OD_STD_STRING_MAX + 1];
};

static int parse_device(struct ctx *c, const cJSON *o, const char *path, struct line_device *d)
{
	co_od_std_opts *so = &d->so;
	char *name = d->name, *hw = d->hw, *sw = d->sw;
	int rc;
	const json_at at = cfg_at(c, path);

	if ((rc = cfg_check_object(c, o, path, device_keys)) ||
	    (rc = cfg_opt_u32(c, o, "device_type", path, (cfg_range){ 0, UINT32_MAX },
			      &so->device_type)) ||
	    (rc = cfg_opt_u32(c, o, "vendor_id", path, (cfg_range){ 0, UINT32_MAX },
			      &so->vendor_id)) ||
	    (rc = cfg_opt_u32(c, o, "product_code", path, (cfg_range){ 0, UINT32_MAX },
			      &so->product_code)) ||
	    (rc = cfg_opt_u32(c, o, "revision", path, (cfg_range){ 0, UINT32_MAX },
			      &so->revision)) ||
	    (rc = cfg_opt_u32(c, o, "serial", path, (cfg_range){ 0, UINT32_MAX }, &so->serial)) ||
	    (rc = json_util_opt_string(o, "name", &at, 0, name, CO_OD_STD_STRING_MAX + 1)) ||
	    (rc = json_util_opt_string(o, "hw_version", &at, 0, hw, CO_OD_STD_STRING_MAX + 1)) ||
	    (rc = json_util_opt_string(o, "sw_version", &at, 0, sw, CO_OD_STD_STRING_MAX + 1)))
		return rc;
	return 0;
}

static int parse_hb_consumers(struct ctx *c, const cJSON *v, const char *path, cogw_line_config *l)
{
	const cJSON *it;
	char p[JSON_PATH_MAX], kp[JSON_PATH_MAX];
	int rc;
	const json_at at = cfg_at(c, p);
	const json_at at_kp = cfg_at(c, kp);

	if (!cJSON_IsArray(v))
		return cfg_fail(c, path, "expected an array, got %s", json_util_kind(v));
	if (cJSON_GetArraySize(v) > COGW_HB_CONSUMERS_MAX)
		return cfg_fail(c, path, "%d entries, at most %d", cJSON_GetArraySize(v),
				COGW_HB_CONSUMERS_MAX);
	cJSON_ArrayForEach(it, v)
	{
		cogw_hb_consumer *h = &l->hb_consumers[l->n_hb_consumers];
		const cJSON *nv, *tv;
		uint64_t u;

		json_util_path_index(p, sizeof(p), path, l->n_hb_consumers);
		if ((rc = cfg_check_object(c, it, p, hb_keys)) ||
		    (rc = json_util_require(it, "node_id", &at, &nv)) ||
		    (rc = json_util_require(it, "time_ms", &at, &tv)))
			return rc;
		json_util_path_key(kp, sizeof(kp), p, "node_id");
		if ((rc = json_util_uint(nv, &at_kp, 1, 127, false, &u)))
			return rc;
		h->node_id = (uint8_t)u;
		if (h->node_id == l->node_id)
			return cfg_fail(c, kp, "%u is this line's own node id", h->node_id);
		for (size_t j = 0; j < l->n_hb_consumers; j++)
			if (l->hb_consumers[j].node_id == h->node_id)
				return cfg_fail(c, kp, "node %u is already monitored (%s[%zu])",
						h->node_id, path, j);
		json_util_path_key(kp, sizeof(kp), p, "time_ms");
		if ((rc = json_util_uint(tv, &at_kp, 1, 65535, false, &u)))
			return rc;
		h->time_ms = (uint16_t)u;
		l->n_hb_consumers++;
	}
	return 0;
}

/* Read the structured keys back from the final OD (see the file comment). */
static void line_sync_from_od(cogw_line_config *l)
{
	uint16_t hb;
	uint32_t per;

	if (!co_od_get_u16(l->od, 0x1017, 0, &hb))
		l->heartbeat_ms = hb;
	if (!co_od_get_u32(l->od, 0x1006, 0, &per))
		l->sync_period_us = per;
	l->n_hb_consumers = 0;
	for (unsigned s = 1; s <= 127; s++) {
		uint32_t v;

		if (co_od_get_u32(l->od, 0x1016, (uint8_t)s, &v))
			break;
		if ((v >> 16 & 0xFF) && (v & 0xFFFF)) {
			cogw_hb_consumer *h = &l->hb_consumers[l->n_hb_consumers++];

			h->node_id = (uint8_t)(v >> 16);
			h->time_ms = (uint16_t)v;
		}
	}
}

/* Every node in "nodes" gets 1F22h:n (its concise DCF, room for at least
 * COGW_NODE_CDCF_ROOM bytes so that a new one can be written over SDO or
 * the mailbox) and, with "date"/"time", 1F26h:n/1F27h:n. They are the
 * defaults too: a reset communication keeps them. The configuration
 * manager (core/cfgmgr.h) reads them when the node boots. */
#define COGW_NODE_CDCF_ROOM (16u * 1024u)
/* A line with a manager gives every other node-ID 1F22h:n too, with this
 * room: a node added at run time (docs/config.md "Nodes at run time") gets
 * its concise DCF without an allocation on the line thread. */
#define COGW_RUNTIME_CDCF_ROOM (4u * 1024u)

static bool node_listed(const cogw_line_config *l, unsigned id)
{
	for (size_t i = 0; i < l->n_nodes; i++)
		if (l->nodes[i].id == id)
			return true;
	return false;
}

uint32_t cogw_node_cdcf_room(const cogw_line_config *l, uint8_t id)
{
	for (size_t i = 0; i < l->n_nodes; i++)
		if (l->nodes[i].id == id)
			return l->nodes[i].config.cdcf_len > COGW_NODE_CDCF_ROOM
				       ? (uint32_t)l->nodes[i].config.cdcf_len
				       : COGW_NODE_CDCF_ROOM;
	return l->manager.enabled && id >= 1 && id <= 127 && id != l->node_id
		       ? COGW_RUNTIME_CDCF_ROOM
		       : 0;
}

static int runtime_node_objects(struct ctx *c, const char *path, cogw_line_config *l)
{
	for (unsigned id = 1; l->manager.enabled && id <= 127; id++) {
		int rc;

		if (id == l->node_id || node_listed(l, id))
			continue;
		rc = co_od_add_cfgmgr_node(l->od, (uint8_t)id, COGW_RUNTIME_CDCF_ROOM);
		if (rc == -ENOMEM)
			return rc;
		if (rc)
			return cfg_fail(c, path, "cannot add 1F22h:%u (%s)", id, strerror(-rc));
	}
	return 0;
}

static int node_objects(struct ctx *c, const char *path, cogw_line_config *l)
{
	for (size_t i = 0; i < l->n_nodes; i++) {
		const cogw_node *n = &l->nodes[i];
		const cogw_node_config *nc = &n->config;
		uint32_t cap = nc->cdcf_len > COGW_NODE_CDCF_ROOM ? (uint32_t)nc->cdcf_len
								  : COGW_NODE_CDCF_ROOM;
		co_od_entry *e;
		int rc = co_od_add_cfgmgr_node(l->od, n->id, cap);

		if (rc == -ENOMEM)
			return rc;
		if (rc || !(e = co_od_find(l->od, CO_CFGMGR_IDX_CDCF, n->id)))
			return cfg_fail(c, path, "cannot add 1F22h:%u for node %u (%s)", n->id,
					n->id, strerror(rc ? -rc : ENOENT));
		if (nc->cdcf_len) {
			if ((rc = co_od_entry_set_default_bytes(e, nc->cdcf,
								(uint32_t)nc->cdcf_len)))
				return rc == -ENOMEM ? rc
						     : cfg_fail(c, path, "1F22h:%u: %s", n->id,
								strerror(-rc));
			co_od_entry_reset(e);
		}
		if (nc->verify) {
			co_od_entry *d = co_od_find(l->od, CO_CFGMGR_IDX_DATE, n->id);
			co_od_entry *t = co_od_find(l->od, CO_CFGMGR_IDX_TIME, n->id);

			if (d && t) {
				co_od_entry_set_default_raw(d, nc->date);
				co_od_entry_set_default_raw(t, nc->time);
				co_od_entry_reset(d);
				co_od_entry_reset(t);
			}
		}
	}
	return 0;
}

int cfg_manager_objects(struct ctx *c, const char *path, cogw_line_config *l);

static int build_od(struct ctx *c, const cJSON *o, const char *path, cogw_line_config *l,
		    co_od_std_opts *so)
{
	char p[JSON_PATH_MAX];
	const cJSON *v;
	int rc;

	rc = co_od_create(&l->od, 256);
	if (rc)
		return rc;
	rc = co_od_add_std_comm(l->od, l->node_id, so);
	if (rc == -ENOMEM)
		return rc;
	if (rc)
		return cfg_fail(c, path, "cannot build the standard objects (%s)", strerror(-rc));
	for (size_t i = 0; i < l->n_hb_consumers; i++) {
		co_od_entry *e = co_od_find(l->od, 0x1016, (uint8_t)(i + 1));

		if (!e)
			return cfg_fail(c, path, "1016h:%zu missing", i + 1);
		co_od_entry_set_default_raw(e, (uint32_t)l->hb_consumers[i].node_id << 16 |
						       l->hb_consumers[i].time_ms);
		co_od_entry_reset(e);
	}
	/* A manager must keep running when one slave's heartbeat is lost:
	 * CiA 301's default reaction (1029h:1 = 0, go pre-operational) would
	 * stop this line's PDO traffic for every other node. "values" may
	 * still set it back. */
	co_od_entry *eb = co_od_find(l->od, 0x1029, 1);
	if (eb) {
		co_od_entry_set_default_raw(eb, 1);
		co_od_entry_reset(eb);
	}
	if ((rc = cfg_gateway_objects(c, l)) || (rc = node_objects(c, path, l)) ||
	    (rc = cfg_unknown_objects(c, path, l)) || (rc = runtime_node_objects(c, path, l)) ||
	    (rc = cfg_manager_objects(c, path, l)))
		return rc;
	v = json_util_get(o, "objects");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "objects");
		if ((rc = cfg_refuse_image_objects(c, v, p)) ||
		    (rc = json_od_add_objects(l->od, v, p, c->msg, sizeof(c->msg))))
			return rc;
	}
	v = json_util_get(o, "values");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "values");
		cfg_route_checks(c, l->od, true);
		rc = json_od_apply_values(l->od, v, p, c->msg, sizeof(c->msg));
		cfg_route_checks(c, l->od, false);
		if (rc || (rc = cfg_check_attached_routes(c, path, l->od)))
			return rc;
	}
	v = json_util_get(o, "app");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "app");
		if ((rc = cfg_parse_app(c, v, p, l)))
			return rc;
	}
	line_sync_from_od(l);
	return 0;
}

static void line_defaults(cogw_line_config *l, size_t idx)
{
	snprintf(l->name, sizeof(l->name), "line%zu", idx);
	l->network_id = (uint16_t)(idx + 1);
	l->rt.priority = 0;
	l->rt.cpu = -1;
	l->sdo_servers = 1;
	l->sdo_clients = 4;
	l->sdo_timeout_ms = 1000;
	l->sdo_block_threshold = 128;
	l->heartbeat_ms = 1000;
	l->pdo = COGW_PDO_OFF;
	l->pdo_scan_max = COGW_PDO_SCAN_MAX_DEFAULT;
	l->id_conflict_quiet_ms = 5000;
	l->fault_quiet_ms = 1000;
	l->unknown = (cogw_unknown_config){ .policy = MBX_UNKNOWN_IGNORE,
					    .heartbeat_ms = 1500,
					    .sdo_timeout_ms = 100 };
	l->device_objects = (cogw_devobj_config){ .read_max_age_ms = 1000,
						  .write_update_ms = 10,
						  .watches = 64 };
	l->app.max_created = 100;
	l->app.max_per_client = 64;
	l->app.indications = 8;
	l->appwd.not_ready_cs = CO_NMT_CS_STOP;
}

static int parse_interface(struct ctx *c, const cJSON *o, const char *path, cogw_line_config *l)
{
	char p[JSON_PATH_MAX];
	const cJSON *v;
	int rc;
	const json_at at = cfg_at(c, path);
	const json_at at_p = cfg_at(c, p);

	if ((rc = json_util_require(o, "interface", &at, &v)))
		return rc;
	json_util_path_key(p, sizeof(p), path, "interface");
	if ((rc = json_util_string(v, &at_p, 1, l->interface, IFNAME_MAX + 1)))
		return rc;
	/* What the kernel's dev_valid_name() refuses. */
	if (!strcmp(l->interface, ".") || !strcmp(l->interface, "..") ||
	    strpbrk(l->interface, "/: \t\n"))
		return cfg_fail(c, p, "\"%s\" is not a valid interface name", l->interface);
	return 0;
}

static int parse_bitrate(struct ctx *c, const cJSON *o, const char *path, cogw_line_config *l)
{
	char p[JSON_PATH_MAX];
	const cJSON *v;
	uint64_t u;
	int rc;
	const json_at at = cfg_at(c, path);
	const json_at at_p = cfg_at(c, p);

	if ((rc = json_util_require(o, "bitrate", &at, &v)))
		return rc;
	json_util_path_key(p, sizeof(p), path, "bitrate");
	if ((rc = json_util_uint(v, &at_p, 1, UINT32_MAX, false, &u)))
		return rc;
	l->bitrate = 0;
	for (size_t i = 0; i < sizeof(cia_bitrates) / sizeof(cia_bitrates[0]); i++)
		if (u == cia_bitrates[i])
			l->bitrate = (uint32_t)u;
	if (!l->bitrate)
		return cfg_fail(
			c, p,
			"%llu is not a CiA 301 bit rate (10000, 20000, 50000, 125000, 250000, "
			"500000, 800000, 1000000)",
			(unsigned long long)u);
	return 0;
}

static int parse_rt(struct ctx *c, const cJSON *v, const char *path, cogw_line_config *l)
{
	char p[JSON_PATH_MAX];
	int64_t s;
	int rc;
	const json_at at = cfg_at(c, p);

	json_util_path_key(p, sizeof(p), path, "rt");
	if ((rc = cfg_check_object(c, v, p, rt_keys)))
		return rc;
	s = l->rt.priority;
	if ((rc = json_util_opt_sint(v, "priority", &at, 0, 99, &s)))
		return rc;
	l->rt.priority = (int)s;
	s = l->rt.cpu;
	if ((rc = json_util_opt_sint(v, "cpu", &at, -1, 1023, &s)))
		return rc;
	l->rt.cpu = (int)s;
	return 0;
}

/* name, interface, bitrate, node_id and rt: who the line is. */
static int parse_line_identity(struct ctx *c, const cJSON *o, const char *path, cogw_line_config *l)
{
	char p[JSON_PATH_MAX];
	const cJSON *v;
	uint64_t u;
	int rc;
	const json_at at = cfg_at(c, path);
	const json_at at_p = cfg_at(c, p);

	if ((rc = json_util_opt_string(o, "name", &at, 1, l->name, sizeof(l->name))))
		return rc;
	json_util_path_key(p, sizeof(p), path, "name");
	if ((rc = cfg_check_name_chars(c, p, l->name)) || (rc = parse_interface(c, o, path, l)) ||
	    (rc = parse_bitrate(c, o, path, l)))
		return rc;

	if ((rc = json_util_require(o, "node_id", &at, &v)))
		return rc;
	json_util_path_key(p, sizeof(p), path, "node_id");
	if ((rc = json_util_uint(v, &at_p, 1, 127, false, &u)))
		return rc;
	l->node_id = (uint8_t)u;

	v = json_util_get(o, "rt");
	return v ? parse_rt(c, v, path, l) : 0;
}

/* "device_objects": reading, writing and watching the slaves' objects
 * (docs/devices.md). */
static int parse_devobj(struct ctx *c, const cJSON *v, const char *path, cogw_devobj_config *d)
{
	int rc;

	if ((rc = cfg_check_object(c, v, path, devobj_keys)) ||
	    (rc = cfg_opt_u32(c, v, "read_max_age_ms", path, (cfg_range){ 0, 86400000 },
			      &d->read_max_age_ms)) ||
	    (rc = cfg_opt_u32(c, v, "write_update_ms", path, (cfg_range){ 0, 60000 },
			      &d->write_update_ms)) ||
	    (rc = cfg_opt_u16(c, v, "watches", path, (cfg_range){ 1, 4096 }, &d->watches)))
		return rc;
	return 0;
}

/* heartbeat_consumers, device, nodes, manager and device_objects: each
 * parsed where present. */
static int parse_line_sections(struct ctx *c, const cJSON *o, const char *path, cogw_line_config *l,
			       struct line_device *d)
{
	char p[JSON_PATH_MAX];
	const cJSON *v;
	int rc;

	v = json_util_get(o, "heartbeat_consumers");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "heartbeat_consumers");
		if ((rc = parse_hb_consumers(c, v, p, l)))
			return rc;
	}
	v = json_util_get(o, "device");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "device");
		if ((rc = parse_device(c, v, p, d)))
			return rc;
	}
	v = json_util_get(o, "nodes");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "nodes");
		if ((rc = cfg_parse_nodes(c, v, p, l)))
			return rc;
	}
	v = json_util_get(o, "manager");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "manager");
		if ((rc = cfg_parse_manager(c, v, p, &l->manager)))
			return rc;
	}
	v = json_util_get(o, "device_objects");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "device_objects");
		if ((rc = parse_devobj(c, v, p, &l->device_objects)))
			return rc;
	}
	/* the network's master asks what it hears; a line without a manager
	 * leaves other masters' devices alone (docs/config.md "Unknown nodes") */
	l->unknown.identify = l->manager.enabled;
	v = json_util_get(o, "unknown_nodes");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "unknown_nodes");
		if ((rc = cfg_parse_unknown(c, v, p, l)))
			return rc;
	}
	return 0;
}

/* The line's numbers: network, SDO channels and times, heartbeat, SYNC,
 * TIME, PDO records, PDO scan. */
static int parse_line_numbers(struct ctx *c, const cJSON *o, const char *path, cogw_line_config *l,
			      co_od_std_opts *so)
{
	int rc;

	if ((rc = cfg_opt_u16(c, o, "network_id", path, (cfg_range){ 1, 127 }, &l->network_id)) ||
	    (rc = cfg_opt_u8(c, o, "sdo_servers", path, (cfg_range){ 1, 128 }, &l->sdo_servers)) ||
	    (rc = cfg_opt_u8(c, o, "sdo_clients", path, (cfg_range){ 0, 128 }, &l->sdo_clients)) ||
	    (rc = cfg_opt_u32(c, o, "sdo_timeout_ms", path, (cfg_range){ 1, 600000 },
			      &l->sdo_timeout_ms)) ||
	    (rc = cfg_opt_u32(c, o, "sdo_block_threshold", path, (cfg_range){ 1, UINT32_MAX },
			      &l->sdo_block_threshold)) ||
	    (rc = cfg_opt_u16(c, o, "heartbeat_ms", path, (cfg_range){ 0, 65535 },
			      &l->heartbeat_ms)) ||
	    (rc = cfg_opt_u32(c, o, "sync_period_us", path, (cfg_range){ 0, UINT32_MAX },
			      &l->sync_period_us)) ||
	    (rc = cfg_opt_u32(c, o, "time_period_ms", path, (cfg_range){ 0, 86400000 },
			      &l->time_period_ms)) ||
	    (rc = cfg_opt_u32(c, o, "id_conflict_quiet_ms", path, (cfg_range){ 100, 3600000 },
			      &l->id_conflict_quiet_ms)) ||
	    (rc = cfg_opt_u32(c, o, "fault_quiet_ms", path, (cfg_range){ 100, 3600000 },
			      &l->fault_quiet_ms)) ||
	    (rc = cfg_opt_u16(c, o, "rpdos", path, (cfg_range){ 0, 512 }, &so->rpdos)) ||
	    (rc = cfg_opt_u16(c, o, "tpdos", path, (cfg_range){ 0, 512 }, &so->tpdos)) ||
	    (rc = cfg_opt_u16(c, o, "pdo_scan_max", path, (cfg_range){ 1, CO_PDO_MAX },
			      &l->pdo_scan_max)) ||
	    (rc = cogw_pdo_mode_parse(o, path, &l->pdo, c->msg, sizeof(c->msg))))
		return rc;
	return 0;
}

int cfg_parse_line(struct ctx *c, const cJSON *o, size_t idx, cogw_line_config *l)
{
	char path[JSON_PATH_MAX];
	struct line_device d = { .name = "cogw" };
	co_od_std_opts *so = &d.so;
	int rc;

	json_util_path_index(path, sizeof(path), "lines", idx);
	if ((rc = cfg_check_object(c, o, path, line_keys)))
		return rc;
	line_defaults(l, idx);
	if ((rc = parse_line_identity(c, o, path, l)))
		return rc;

	co_od_std_opts_init(so);
	if ((rc = parse_line_numbers(c, o, path, l, so)) ||
	    (rc = parse_line_sections(c, o, path, l, &d)) ||
	    (rc = cogw_line_pdo_check(l, path, c->msg, sizeof(c->msg))))
		return rc;

	so->device_name = d.name;
	so->hw_version = d.hw;
	so->sw_version = d.sw;
	so->heartbeat_ms = l->heartbeat_ms;
	so->sync_period_us = l->sync_period_us;
	/* 1005h bit 30: we produce SYNC when a period is configured. */
	so->sync_cob_id = l->sync_period_us ? 0x40000080u : 0x80u;
	/* 1012h bit 30: we produce TIME when a period is configured. */
	so->time_cob_id = l->time_period_ms ? 0x40000100u : 0x100u;
	so->sdo_servers = l->sdo_servers;
	so->sdo_clients = l->sdo_clients;
	so->gateway = true;
	return build_od(c, o, path, l, so);
}

int cfg_check_unique(struct ctx *c, const cogw_config *cfg, size_t i)
{
	const cogw_line_config *l = &cfg->lines[i];
	char p[JSON_PATH_MAX];

	for (size_t j = 0; j < i; j++) {
		const cogw_line_config *o = &cfg->lines[j];

		if (!strcmp(o->name, l->name)) {
			snprintf(p, sizeof(p), "lines[%zu].name", i);
			return cfg_fail(c, p, "\"%s\" is already used by lines[%zu]", l->name, j);
		}
		if (!strcmp(o->interface, l->interface)) {
			snprintf(p, sizeof(p), "lines[%zu].interface", i);
			return cfg_fail(c, p, "\"%s\" is already used by lines[%zu]", l->interface,
					j);
		}
		if (o->network_id == l->network_id) {
			snprintf(p, sizeof(p), "lines[%zu].network_id", i);
			return cfg_fail(c, p, "%u is already used by lines[%zu]", l->network_id, j);
		}
	}
	return 0;
}
