/* SPDX-License-Identifier: MIT */
/*
 * apps/common/config.c - cogwd's JSON configuration: parse, validate, build
 * each line's object dictionary (see config.h, docs/config.md).
 *
 * Order of a line's OD: the standard communication objects for its node id
 * (core/od_std.h) from the line's keys, then "objects", then "values". The
 * line's structured keys (heartbeat_ms, heartbeat_consumers,
 * sync_period_us) are read back from the OD at the end, so that a "values"
 * entry for 1016h/1017h/1006h and the struct never disagree.
 *
 * Validation is complete before the daemon touches anything: the first
 * error ends the load with one message "source: path: reason".
 */
#include "apps/common/config.h"
#include "apps/common/file_read.h"
#include "gateway/convention.h"
#include "gateway/image.h"
#include "gateway/route.h"

#include <errno.h>
#include <fcntl.h>
#include <pwd.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <cjson/cJSON.h>

#include "apps/common/json_od.h"
#include "apps/common/json_util.h"
#include "apps/common/pdo_config.h"
#include "core/cfgmgr.h"
#include "core/manager.h"
#include "core/nmt.h"
#include "core/swmgr.h"
#include "core/od_std.h"

#define CONFIG_FILE_MAX (4u * 1024u * 1024u)
#define IFNAME_MAX 15u /* IFNAMSIZ - 1 */
/* mirror mailbox/proto.h MBX_MSG_MIN / MBX_MSG_MAX */
#define MSG_SIZE_MIN 256u
#define MSG_SIZE_MAX 65535u

static const char *const top_keys[] = { "version", "state_dir",   "mlockall", "watchdog_check_ms",
					"mailbox", "file_memory", "lines",    "gateway",
					"debug",   "comment",     NULL };
static const char *const gateway_keys[] = { "routes", "process_image", "forward", "comment", NULL };
static const char *const forward_keys[] = { "from", "to", "image", "comment", NULL };
static const char *const dev_ref_keys[] = { "line", "node", "index", "sub", "comment", NULL };
static const char *const route_keys[] = { "network", "line", "router", "comment", NULL };
static const char *const mailbox_keys[] = { "instance",
					    "depth",
					    "msg_size",
					    "queue_mode",
					    "max_clients",
					    "lease_ms",
					    "max_transfer",
					    "max_clients_per_uid",
					    "max_outstanding",
					    "max_read_outstanding",
					    "write_reserve",
					    "max_request_timeout_ms",
					    "transfer_slots",
					    "max_transfers_per_client",
					    "transfer_stall_ms",
					    "transfer_lifetime_ms",
					    "transfer_memory",
					    "default_access",
					    "rules",
					    "comment",
					    NULL };
static const char *const rule_keys[] = { "user", "uid", "access", "comment", NULL };
static const char *const debug_keys[] = { "stall_signal", "stall_ms", "comment", NULL };
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
					 "comment",        NULL };
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

/* Everything a load needs, passed down instead of a dozen parameters. */
struct ctx {
	const char *source;
	char base_dir[256];              /* directory of the source file ("" = cwd) */
	const cogw_embedded_file *files; /* the embedded default's own files */
	char *err;
	size_t errlen;
	char msg[512]; /* "path: reason" before the source is prefixed */
	/* CiA 302-7 gateway, known before the lines are built (every line's
	 * 1F2Ch gets the routes to all lines' networks as defaults) */
	size_t n_lines;
	uint16_t line_net[COGW_LINES_MAX];      /* network of each line */
	uint32_t route_default[GW_NET_MAX + 1]; /* 1F2Ch defaults */
	uint16_t route_seen[GW_NET_MAX + 1];    /* gateway.routes[i] + 1 */
	const cJSON *process_image;             /* gateway.process_image */
	cogw_file_set *read;                    /* the files loaded so far (the config's) */
};

static int fail(struct ctx *c, const char *path, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static int fail(struct ctx *c, const char *path, const char *fmt, ...)
{
	char reason[256];
	va_list ap;

	va_start(ap, fmt);
	vsnprintf(reason, sizeof(reason), fmt, ap);
	va_end(ap);
	return json_util_fail(c->msg, sizeof(c->msg), path, "%s", reason);
}

/* ---- small typed readers into struct fields ----------------------------------- */

static int opt_u32(struct ctx *c, const cJSON *o, const char *key, const char *path, uint64_t min,
		   uint64_t max, uint32_t *out)
{
	uint64_t v = *out;
	int rc = json_util_opt_uint(o, key, path, min, max, &v, c->msg, sizeof(c->msg));

	if (!rc)
		*out = (uint32_t)v;
	return rc;
}

static int opt_u16(struct ctx *c, const cJSON *o, const char *key, const char *path, uint64_t min,
		   uint64_t max, uint16_t *out)
{
	uint32_t v = *out;
	int rc = opt_u32(c, o, key, path, min, max, &v);

	if (!rc)
		*out = (uint16_t)v;
	return rc;
}

static int opt_u8(struct ctx *c, const cJSON *o, const char *key, const char *path, uint64_t min,
		  uint64_t max, uint8_t *out)
{
	uint32_t v = *out;
	int rc = opt_u32(c, o, key, path, min, max, &v);

	if (!rc)
		*out = (uint8_t)v;
	return rc;
}

static int opt_unsigned(struct ctx *c, const cJSON *o, const char *key, const char *path,
			uint64_t min, uint64_t max, unsigned *out)
{
	uint32_t v = *out;
	int rc = opt_u32(c, o, key, path, min, max, &v);

	if (!rc)
		*out = v;
	return rc;
}

static int check_object(struct ctx *c, const cJSON *o, const char *path, const char *const *keys)
{
	return json_util_check_object(o, path, keys, c->msg, sizeof(c->msg));
}

/* Names that end up in queue names and logs: [A-Za-z0-9_-]. */
static int check_name_chars(struct ctx *c, const char *path, const char *s)
{
	for (const char *p = s; *p; p++) {
		if ((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') ||
		    (*p >= '0' && *p <= '9') || *p == '_' || *p == '-')
			continue;
		return fail(c, path, "\"%s\" may contain only letters, digits, '_' and '-'", s);
	}
	return 0;
}

static int parse_access_word(struct ctx *c, const cJSON *v, const char *path, uint8_t *out)
{
	static const char *const words[] = { "none", "read", "write" };
	char r[64];

	if (cJSON_IsString(v)) {
		for (unsigned i = 0; i < 3; i++) {
			if (!strcmp(v->valuestring, words[i])) {
				*out = (uint8_t)i; /* = cogw_access_level */
				return 0;
			}
		}
	}
	json_util_repr(v, r, sizeof(r));
	return fail(c, path, "unknown access %s (one of none, read, write)", r);
}

/* ---- mailbox ------------------------------------------------------------------ */

static int parse_rule(struct ctx *c, const cJSON *o, const char *path, cogw_access_rule *r)
{
	char p[JSON_PATH_MAX];
	const cJSON *user, *uid, *acc;
	int rc;

	if ((rc = check_object(c, o, path, rule_keys)))
		return rc;
	user = json_util_get(o, "user");
	uid = json_util_get(o, "uid");
	if (!user == !uid)
		return fail(c, path, "give either \"user\" or \"uid\"");
	if (user) {
		char name[256], buf[4096];
		struct passwd pw, *res = NULL;

		json_util_path_key(p, sizeof(p), path, "user");
		if ((rc = json_util_string(user, p, 1, name, sizeof(name), c->msg, sizeof(c->msg))))
			return rc;
		if (getpwnam_r(name, &pw, buf, sizeof(buf), &res) != 0 || !res)
			return fail(c, p, "unknown user \"%s\"", name);
		r->uid = res->pw_uid;
	} else {
		uint64_t u;

		json_util_path_key(p, sizeof(p), path, "uid");
		if ((rc = json_util_uint(uid, p, 0, UINT32_MAX - 1, false, &u, c->msg,
					 sizeof(c->msg))))
			return rc;
		r->uid = (uid_t)u;
	}
	if ((rc = json_util_require(o, "access", path, &acc, c->msg, sizeof(c->msg))))
		return rc;
	json_util_path_key(p, sizeof(p), path, "access");
	return parse_access_word(c, acc, p, &r->access);
}

/* The per-user / per-client limits that depend on each other (ranges and
 * defaults: docs/config.md, docs/mailbox.md "Security model"). */
static int parse_mailbox_limits(struct ctx *c, const cJSON *o, cogw_mailbox_config *m)
{
	const char *path = "mailbox";
	char p[JSON_PATH_MAX];
	int rc;

	if ((rc = opt_unsigned(c, o, "max_read_outstanding", path, 1, 65535,
			       &m->max_read_outstanding)) ||
	    (rc = opt_unsigned(c, o, "write_reserve", path, 1, 1023, &m->write_reserve)) ||
	    (rc = opt_unsigned(c, o, "transfer_slots", path, 1, 255, &m->transfer_slots)) ||
	    (rc = opt_unsigned(c, o, "max_transfers_per_client", path, 1, 255,
			       &m->max_transfers_per_client)) ||
	    (rc = opt_unsigned(c, o, "transfer_stall_ms", path, 10, 600000u,
			       &m->transfer_stall_ms)) ||
	    (rc = opt_unsigned(c, o, "transfer_lifetime_ms", path, 100, 86400000u,
			       &m->transfer_lifetime_ms)) ||
	    (rc = opt_unsigned(c, o, "transfer_memory", path, 4096, UINT32_MAX,
			       &m->transfer_memory)))
		return rc;
	/* A budget below max_transfer would refuse the largest transfer the
	 * configuration allows, every time. */
	if (m->transfer_memory < m->max_transfer) {
		json_util_path_key(p, sizeof(p), path, "transfer_memory");
		return fail(c, p,
			    "%u is less than max_transfer (%u): no transfer that large could run",
			    m->transfer_memory, m->max_transfer);
	}
	/* A reserve as large as the table would lock every read-only client
	 * out; 0 is not offered: one slot kept for writers is what makes a
	 * flood of read-only registrations harmless. */
	if (m->write_reserve && m->write_reserve >= m->max_clients) {
		json_util_path_key(p, sizeof(p), path, "write_reserve");
		return fail(c, p, "%u leaves read-only clients no slot (max_clients is %u)",
			    m->write_reserve, m->max_clients);
	}
	if (m->max_transfers_per_client && m->max_transfers_per_client > m->transfer_slots) {
		json_util_path_key(p, sizeof(p), path, "max_transfers_per_client");
		return fail(c, p, "%u is more than transfer_slots (%u)",
			    m->max_transfers_per_client, m->transfer_slots);
	}
	if (m->max_clients_per_uid > m->max_clients) {
		json_util_path_key(p, sizeof(p), path, "max_clients_per_uid");
		return fail(c, p, "%u is more than max_clients (%u)", m->max_clients_per_uid,
			    m->max_clients);
	}
	return 0;
}

static int parse_mailbox(struct ctx *c, const cJSON *o, cogw_mailbox_config *m)
{
	const char *path = "mailbox";
	char p[JSON_PATH_MAX];
	const cJSON *v;
	int rc;

	if ((rc = check_object(c, o, path, mailbox_keys)))
		return rc;
	if ((rc = json_util_opt_string(o, "instance", path, 1, m->instance, sizeof(m->instance),
				       c->msg, sizeof(c->msg))))
		return rc;
	json_util_path_key(p, sizeof(p), path, "instance");
	if ((rc = check_name_chars(c, p, m->instance)) ||
	    (rc = opt_unsigned(c, o, "depth", path, 1, 65536, &m->depth)) ||
	    (rc = opt_unsigned(c, o, "msg_size", path, MSG_SIZE_MIN, MSG_SIZE_MAX, &m->msg_size)) ||
	    (rc = opt_unsigned(c, o, "max_clients", path, 1, 1024, &m->max_clients)) ||
	    (rc = opt_unsigned(c, o, "lease_ms", path, 0, 86400000u, &m->lease_ms)) ||
	    (rc = opt_unsigned(c, o, "max_transfer", path, 1, 256u << 20, &m->max_transfer)) ||
	    (rc = opt_unsigned(c, o, "max_clients_per_uid", path, 1, 1024,
			       &m->max_clients_per_uid)) ||
	    (rc = opt_unsigned(c, o, "max_outstanding", path, 1, 1024, &m->max_outstanding)) ||
	    (rc = opt_unsigned(c, o, "max_request_timeout_ms", path, 1, 3600000u,
			       &m->max_request_timeout_ms)) ||
	    (rc = parse_mailbox_limits(c, o, m)))
		return rc;
	v = json_util_get(o, "queue_mode");
	if (v) {
		uint64_t mode;

		/* A string, because JSON has no octal: 660 would be 01224. */
		json_util_path_key(p, sizeof(p), path, "queue_mode");
		if (!cJSON_IsString(v) || v->valuestring[0] != '0')
			return fail(c, p, "expected an octal string like \"0620\"");
		if ((rc = json_util_uint(v, p, 0, 0777, false, &mode, c->msg, sizeof(c->msg))))
			return rc;
		/* Every command carries its client's token: a command queue
		 * others can read gives them every client's rights. */
		if (mode & 0044)
			return fail(c, p,
				    "clients could read other clients' tokens: "
				    "no read bit for group or others (e.g. "
				    "\"0620\" or \"0622\")");
		m->queue_mode = (unsigned)mode;
	}
	v = json_util_get(o, "default_access");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "default_access");
		if ((rc = parse_access_word(c, v, p, &m->default_access)))
			return rc;
	}
	v = json_util_get(o, "rules");
	if (v) {
		const cJSON *it;
		char rp[JSON_PATH_MAX];

		json_util_path_key(p, sizeof(p), path, "rules");
		if (!cJSON_IsArray(v))
			return fail(c, p, "expected an array, got %s", json_util_kind(v));
		if (cJSON_GetArraySize(v) > COGW_ACCESS_RULES_MAX)
			return fail(c, p, "%d rules, at most %d", cJSON_GetArraySize(v),
				    COGW_ACCESS_RULES_MAX);
		cJSON_ArrayForEach(it, v)
		{
			cogw_access_rule *r = &m->rules[m->n_rules];

			json_util_path_index(rp, sizeof(rp), p, m->n_rules);
			if ((rc = parse_rule(c, it, rp, r)))
				return rc;
			for (size_t j = 0; j < m->n_rules; j++)
				if (m->rules[j].uid == r->uid)
					return fail(c, rp, "uid %u already has a rule (%s[%zu])",
						    (unsigned)r->uid, p, j);
			m->n_rules++;
		}
	}
	return 0;
}

/* ---- lines --------------------------------------------------------------------- */

static int parse_device(struct ctx *c, const cJSON *o, const char *path, co_od_std_opts *so,
			char *name, char *hw, char *sw)
{
	int rc;

	if ((rc = check_object(c, o, path, device_keys)) ||
	    (rc = opt_u32(c, o, "device_type", path, 0, UINT32_MAX, &so->device_type)) ||
	    (rc = opt_u32(c, o, "vendor_id", path, 0, UINT32_MAX, &so->vendor_id)) ||
	    (rc = opt_u32(c, o, "product_code", path, 0, UINT32_MAX, &so->product_code)) ||
	    (rc = opt_u32(c, o, "revision", path, 0, UINT32_MAX, &so->revision)) ||
	    (rc = opt_u32(c, o, "serial", path, 0, UINT32_MAX, &so->serial)) ||
	    (rc = json_util_opt_string(o, "name", path, 0, name, CO_OD_STD_STRING_MAX + 1, c->msg,
				       sizeof(c->msg))) ||
	    (rc = json_util_opt_string(o, "hw_version", path, 0, hw, CO_OD_STD_STRING_MAX + 1,
				       c->msg, sizeof(c->msg))) ||
	    (rc = json_util_opt_string(o, "sw_version", path, 0, sw, CO_OD_STD_STRING_MAX + 1,
				       c->msg, sizeof(c->msg))))
		return rc;
	return 0;
}

static int parse_hb_consumers(struct ctx *c, const cJSON *v, const char *path, cogw_line_config *l)
{
	const cJSON *it;
	char p[JSON_PATH_MAX], kp[JSON_PATH_MAX];
	int rc;

	if (!cJSON_IsArray(v))
		return fail(c, path, "expected an array, got %s", json_util_kind(v));
	if (cJSON_GetArraySize(v) > COGW_HB_CONSUMERS_MAX)
		return fail(c, path, "%d entries, at most %d", cJSON_GetArraySize(v),
			    COGW_HB_CONSUMERS_MAX);
	cJSON_ArrayForEach(it, v)
	{
		cogw_hb_consumer *h = &l->hb_consumers[l->n_hb_consumers];
		const cJSON *nv, *tv;
		uint64_t u;

		json_util_path_index(p, sizeof(p), path, l->n_hb_consumers);
		if ((rc = check_object(c, it, p, hb_keys)) ||
		    (rc = json_util_require(it, "node_id", p, &nv, c->msg, sizeof(c->msg))) ||
		    (rc = json_util_require(it, "time_ms", p, &tv, c->msg, sizeof(c->msg))))
			return rc;
		json_util_path_key(kp, sizeof(kp), p, "node_id");
		if ((rc = json_util_uint(nv, kp, 1, 127, false, &u, c->msg, sizeof(c->msg))))
			return rc;
		h->node_id = (uint8_t)u;
		if (h->node_id == l->node_id)
			return fail(c, kp, "%u is this line's own node id", h->node_id);
		for (size_t j = 0; j < l->n_hb_consumers; j++)
			if (l->hb_consumers[j].node_id == h->node_id)
				return fail(c, kp, "node %u is already monitored (%s[%zu])",
					    h->node_id, path, j);
		json_util_path_key(kp, sizeof(kp), p, "time_ms");
		if ((rc = json_util_uint(tv, kp, 1, 65535, false, &u, c->msg, sizeof(c->msg))))
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

/* ---- CiA 302-7 gateway ------------------------------------------------------------ */

/* The gateway objects of one line, before its own "objects" and "values"
 * (which may override them): this line's network id (5F00h), 1F2Ch with
 * the routes to every line's network and gateway.routes, and the shared
 * process image (gateway.process_image, the same objects on every line). */
static int gateway_objects(struct ctx *c, cogw_line_config *l)
{
	co_od_entry *e;
	int rc;

	rc = co_od_add_num(l->od, GW_OBJ_NETWORK_ID, 0, CO_T_UNSIGNED8, CO_ACC_CO, l->network_id,
			   &e);
	if (rc)
		return fail(c, "lines", "cannot add %04Xh (%s)", GW_OBJ_NETWORK_ID, strerror(-rc));
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
static int refuse_image_objects(struct ctx *c, const cJSON *objects, const char *path)
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
			return fail(c, p,
				    "%04Xh: B000h..BFFFh is the shared process image of all "
				    "lines: define it in gateway.process_image",
				    index);
	}
	return 0;
}

/* Check the process image objects: B000h..BFFFh, numeric, at most 8 bytes
 * (what a classic CAN PDO can carry), PDO-mappable. */
static int check_image(struct ctx *c, const co_od *od)
{
	for (size_t i = 0; i < co_od_count(od); i++) {
		const co_od_entry *e = co_od_at(od, i);

		if (e->obj_code != CO_OBJ_VAR && e->sub == 0)
			continue; /* sub 0 of an ARRAY/RECORD: the count */
		if (!gw_image_in_range(e->index))
			return fail(c, "gateway.process_image", "%04Xh is outside B000h..BFFFh",
				    e->index);
		if (co_type_is_variable((co_type)e->type) || e->size > 8)
			return fail(c, "gateway.process_image",
				    "%04Xh:%02X: a %s cannot be forwarded by PDO "
				    "(numeric types of at most 8 bytes)",
				    e->index, e->sub, co_type_to_string((co_type)e->type));
		if (!(e->access & (CO_ACC_RPDO | CO_ACC_TPDO)))
			return fail(c, "gateway.process_image",
				    "%04Xh:%02X is not PDO-mappable (set \"pdo\": true)", e->index,
				    e->sub);
	}
	return 0;
}

/* Every line's network id, read ahead of the lines (validated again, with
 * its path, when the line itself is parsed). */
static void scan_networks(struct ctx *c, const cJSON *lines)
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

static void route_checks(struct ctx *c, co_od *od, bool on)
{
	for (unsigned n = GW_NET_MIN; n <= GW_NET_MAX; n++)
		(void)co_od_set_hooks(od, GW_OBJ_ROUTES, (uint8_t)n,
				      on ? &config_route_hooks : NULL, on ? c : NULL);
}

/* A network attached to one of our lines has one route, to that line: a
 * "values" entry that sends it elsewhere is a second route for it. */
static int check_attached_routes(struct ctx *c, const char *path, const co_od *od)
{
	for (size_t i = 0; i < c->n_lines; i++) {
		uint16_t net = c->line_net[i];
		const co_od_entry *e = co_od_find(od, GW_OBJ_ROUTES, (uint8_t)net);
		uint32_t v = e ? (uint32_t)co_od_entry_raw(e) : 0;
		char p[JSON_PATH_MAX];

		if (!v || v == c->route_default[net])
			continue;
		json_util_path_key(p, sizeof(p), path, "values");
		return fail(c, p,
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

	json_util_path_index(path, sizeof(path), "gateway.routes", idx);
	json_util_path_key(pn, sizeof(pn), path, "network");
	json_util_path_key(pl, sizeof(pl), path, "line");
	json_util_path_key(pr, sizeof(pr), path, "router");
	if ((rc = check_object(c, o, path, route_keys)))
		return rc;
	if ((rc = json_util_require(o, "network", path, &v, c->msg, sizeof(c->msg))) ||
	    (rc = json_util_uint(v, pn, GW_NET_MIN, GW_NET_MAX, false, &net, c->msg,
				 sizeof(c->msg))) ||
	    (rc = json_util_require(o, "line", path, &v, c->msg, sizeof(c->msg))) ||
	    (rc = json_util_uint(v, pl, 0, COGW_LINES_MAX - 1, false, &line, c->msg,
				 sizeof(c->msg))))
		return rc;
	if (line >= c->n_lines)
		return fail(c, pl, "line %u does not exist (%zu lines)", (unsigned)line,
			    c->n_lines);
	v = json_util_get(o, "router");
	if (v && (rc = json_util_uint(v, pr, 1, 127, false, &router, c->msg, sizeof(c->msg))))
		return rc;
	for (size_t i = 0; i < c->n_lines; i++)
		if (c->line_net[i] == net)
			return fail(c, path,
				    "network %u is attached to lines[%zu]: it needs no route",
				    (unsigned)net, i);
	if (!router)
		return fail(c, path, "network %u is not attached here: name its next router",
			    (unsigned)net);
	if (c->route_seen[net])
		return fail(c, pn, "network %u has a route already (gateway.routes[%u])",
			    (unsigned)net, c->route_seen[net] - 1);
	c->route_seen[net] = (uint16_t)(idx + 1);
	c->route_default[net] = gw_route_entry_encode(
		(gw_route_entry){ true, (uint8_t)line, (uint8_t)router });
	return 0;
}

static int parse_gateway(struct ctx *c, const cJSON *o)
{
	const cJSON *v, *it;
	size_t i = 0;
	int rc;

	if ((rc = check_object(c, o, "gateway", gateway_keys)))
		return rc;
	v = json_util_get(o, "routes");
	if (v) {
		if (!cJSON_IsArray(v))
			return fail(c, "gateway.routes", "expected an array, got %s",
				    json_util_kind(v));
		/* one route per network at most, networks 1..127 */
		if (cJSON_GetArraySize(v) > (int)GW_NET_MAX)
			return fail(c, "gateway.routes", "%d routes, at most %u (one per network)",
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
			rc = check_image(c, od);
		co_od_destroy(od);
		if (rc)
			return rc;
		c->process_image = v;
	}
	return 0;
}

/* Every node in "nodes" gets 1F22h:n (its concise DCF, room for at least
 * COGW_NODE_CDCF_ROOM bytes so that a new one can be written over SDO or
 * the mailbox) and, with "date"/"time", 1F26h:n/1F27h:n. They are the
 * defaults too: a reset communication keeps them. The configuration
 * manager (core/cfgmgr.h) reads them when the node boots. */
#define COGW_NODE_CDCF_ROOM (16u * 1024u)
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
			return fail(c, path, "cannot add 1F22h:%u for node %u (%s)", n->id, n->id,
				    strerror(rc ? -rc : ENOENT));
		if (nc->cdcf_len) {
			if ((rc = co_od_entry_set_default_bytes(e, nc->cdcf,
								(uint32_t)nc->cdcf_len)))
				return rc == -ENOMEM ? rc
						     : fail(c, path, "1F22h:%u: %s", n->id,
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

static int manager_objects(struct ctx *c, const char *path, cogw_line_config *l);

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
		return fail(c, path, "cannot build the standard objects (%s)", strerror(-rc));
	for (size_t i = 0; i < l->n_hb_consumers; i++) {
		co_od_entry *e = co_od_find(l->od, 0x1016, (uint8_t)(i + 1));

		if (!e)
			return fail(c, path, "1016h:%zu missing", i + 1);
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
	if ((rc = gateway_objects(c, l)) || (rc = node_objects(c, path, l)) ||
	    (rc = manager_objects(c, path, l)))
		return rc;
	v = json_util_get(o, "objects");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "objects");
		if ((rc = refuse_image_objects(c, v, p)) ||
		    (rc = json_od_add_objects(l->od, v, p, c->msg, sizeof(c->msg))))
			return rc;
	}
	v = json_util_get(o, "values");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "values");
		route_checks(c, l->od, true);
		rc = json_od_apply_values(l->od, v, p, c->msg, sizeof(c->msg));
		route_checks(c, l->od, false);
		if (rc || (rc = check_attached_routes(c, path, l->od)))
			return rc;
	}
	line_sync_from_od(l);
	return 0;
}

static int opt_flag(struct ctx *c, const cJSON *o, const char *key, const char *path, uint32_t bit,
		    bool def, uint32_t *bits)
{
	bool b = def;
	int rc = json_util_opt_bool(o, key, path, &b, c->msg, sizeof(c->msg));

	if (!rc && b)
		*bits |= bit;
	return rc;
}

/* An UNSIGNED32 given as a number or a "0x..." string. */
static int opt_u32_hex(struct ctx *c, const cJSON *o, const char *key, const char *path,
		       uint32_t *out)
{
	const cJSON *v = json_util_get(o, key);
	char p[JSON_PATH_MAX];
	uint64_t u;
	int rc;

	if (!v)
		return 0;
	json_util_path_key(p, sizeof(p), path, key);
	if ((rc = json_util_uint(v, p, 0, UINT32_MAX, true, &u, c->msg, sizeof(c->msg))))
		return rc;
	*out = (uint32_t)u;
	return 0;
}

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
		return fail(c, p, "file name too long");
	rc = cogw_file_set_get(c->read, n->program_file, COGW_PROGRAM_MAX, &n->program,
			       &n->program_len, why, sizeof(why));
	if (rc == -ENOMEM)
		return rc;
	if (rc)
		return fail(c, p, "%s", why);
	if (!n->program_len) {
		n->program = NULL;
		return fail(c, p, "%s: a program image of 1..%u bytes, not 0", n->program_file,
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

	if ((rc = opt_u32_hex(c, it, "software_id", np, &n->software_id)) ||
	    (rc = json_util_opt_bool(it, "software_update", np, &update, c->msg, sizeof(c->msg))))
		return rc;
	if (n->software_id)
		*a |= CO_SWMGR_F81_CHECK;
	if (!update && !prog)
		return 0;
	json_util_path_key(p, sizeof(p), np, update ? "software_update" : "program");
	if (!update || !prog || !n->software_id)
		return fail(c, p,
			    "\"software_update\": true, \"program\" and a non-zero "
			    "\"software_id\" go together (node %u)",
			    n->id);
	*a |= CO_SWMGR_F81_UPDATE;
	json_util_path_key(p, sizeof(p), np, "program");
	if ((rc = json_util_string(prog, p, 1, name, sizeof(name), c->msg, sizeof(c->msg))))
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

	if ((rc = json_util_opt_string(it, "state", np, 1, what, sizeof(what), c->msg,
				       sizeof(c->msg))))
		return rc;
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++)
		if (!strcmp(what, names[i].name)) {
			*state = names[i].nmt;
			return 0;
		}
	json_util_path_key(p, sizeof(p), np, "state");
	return fail(c, p, "\"%s\": expected \"operational\", \"pre-operational\" or \"stopped\"",
		    what);
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

	if ((rc = opt_flag(c, it, "boot", np, CO_MGR_1F81_BOOT, true, &a)) ||
	    (rc = opt_flag(c, it, "mandatory", np, CO_MGR_1F81_MANDATORY, false, &a)) ||
	    (rc = opt_flag(c, it, "keep_alive", np, CO_MGR_1F81_KEEP_ALIVE, false, &a)) ||
	    (rc = opt_u32(c, it, "retry_factor", np, 0, 255, &factor)) ||
	    (rc = opt_u32(c, it, "guard_time_ms", np, 0, 65535, &guard)) ||
	    (rc = opt_u16(c, it, "heartbeat_ms", np, 0, 65535, &hb)) ||
	    (rc = json_util_opt_bool(it, "keep_op", np, &keep_op, c->msg, sizeof(c->msg))))
		return rc;
	for (int i = 0; i < 5; i++)
		if ((rc = opt_u32_hex(c, it, id_keys[i], np, &n->identity[i])))
			return rc;
	if (hb && guard) {
		char p[JSON_PATH_MAX];
		json_util_path_key(p, sizeof(p), np, "guard_time_ms");
		return fail(c, p, "node %u has heartbeat_ms too: supervise it one way", n->id);
	}
	if ((rc = parse_node_software(c, it, np, n, &a)) ||
	    (rc = parse_node_state(c, it, np, &n->target_state)))
		return rc;
	n->assignment = a | factor << 8 | guard << 16;
	n->heartbeat_ms = hb;
	n->keep_op = keep_op;
	return 0;
}

/* "manager": the line's CiA 302-2 manager; 1F80h from names. */
static int parse_manager(struct ctx *c, const cJSON *o, const char *path, cogw_manager_config *m)
{
	char p[JSON_PATH_MAX], what[16] = "node";
	uint32_t b = 0;
	int rc;

	if ((rc = check_object(c, o, path, manager_keys)))
		return rc;
	m->enabled = true;
	m->retry_ms = 1000;
	m->reset_wait_ms = 1000;
	m->sdo_timeout_ms = 500;
	m->boot_time_ms = 0;
	if ((rc = opt_flag(c, o, "master", path, CO_MGR_1F80_MASTER, true, &b)) ||
	    (rc = opt_flag(c, o, "start_all", path, CO_MGR_1F80_START_ALL, false, &b)))
		return rc;
	/* bits 2 and 3 say what the manager may NOT do: the names say what it
	 * does */
	uint32_t self = 0, slaves = 0;
	if ((rc = opt_flag(c, o, "self_start", path, 1, true, &self)) ||
	    (rc = opt_flag(c, o, "start_slaves", path, 1, true, &slaves)))
		return rc;
	if (!self)
		b |= CO_MGR_1F80_NO_SELF_START;
	if (!slaves)
		b |= CO_MGR_1F80_APP_STARTS_SLAVES;
	if ((rc = json_util_opt_string(o, "on_mandatory_error", path, 1, what, sizeof(what), c->msg,
				       sizeof(c->msg))))
		return rc;
	json_util_path_key(p, sizeof(p), path, "on_mandatory_error");
	if (!strcmp(what, "reset_all"))
		b |= CO_MGR_1F80_RESET_ALL_ON_ERROR;
	else if (!strcmp(what, "stop_all"))
		b |= CO_MGR_1F80_STOP_ALL_ON_ERROR;
	else if (strcmp(what, "node"))
		return fail(c, p, "\"%s\": expected \"node\", \"reset_all\" or \"stop_all\"", what);
	m->nmt_startup = b;
	if ((rc = opt_u32(c, o, "boot_time_ms", path, 0, 3600000, &m->boot_time_ms)) ||
	    (rc = opt_u32(c, o, "retry_ms", path, 10, 3600000, &m->retry_ms)) ||
	    (rc = opt_u32(c, o, "scan_ms", path, 0, 3600000, &m->scan_ms)) ||
	    (rc = opt_u32(c, o, "reset_wait_ms", path, 1, 60000, &m->reset_wait_ms)) ||
	    (rc = opt_u32(c, o, "sdo_timeout_ms", path, 1, 60000, &m->sdo_timeout_ms)) ||
	    (rc = opt_u8(c, o, "max_parallel", path, 0, 128, &m->max_parallel)) ||
	    (rc = json_util_opt_bool(o, "accept_remote_nmt", path, &m->accept_remote_nmt, c->msg,
				     sizeof(c->msg))))
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

static int manager_objects(struct ctx *c, const char *path, cogw_line_config *l)
{
	const cogw_manager_config *m = &l->manager;
	int rc;

	if (!m->enabled)
		return 0;
	if ((rc = co_od_add_manager_defaults(l->od, m->nmt_startup)) < 0)
		return rc == -ENOMEM ? rc
				     : fail(c, path, "cannot add the manager objects (%s)",
					    strerror(-rc));
	if ((rc = set_default(l->od, 0x1F80, 0, m->nmt_startup)) ||
	    (rc = set_default(l->od, 0x1F89, 0, m->boot_time_ms)))
		return fail(c, path, "1F80h/1F89h: %s", strerror(-rc));
	for (size_t i = 0; i < l->n_nodes; i++) {
		const cogw_node *n = &l->nodes[i];
		if ((rc = set_default(l->od, 0x1F81, n->id, n->assignment)))
			return fail(c, path, "1F81h:%u: %s", n->id, strerror(-rc));
		for (int k = 0; k < 5; k++)
			if ((rc = set_default(l->od, (uint16_t)(0x1F84 + k), n->id,
					      n->identity[k])))
				return fail(c, path, "%04Xh:%u: %s", 0x1F84 + k, n->id,
					    strerror(-rc));
		if (n->software_id &&
		    ((rc = co_od_add_swmgr_defaults(l->od)) ||
		     (rc = set_default(l->od, CO_SWMGR_IDX_EXPECTED, n->id, n->software_id))))
			return fail(c, path, "1F55h:%u: %s", n->id, strerror(-rc));
		if (!n->heartbeat_ms)
			continue;
		uint8_t free_sub = 0, subs = 0;
		(void)co_od_get_u8(l->od, 0x1016, 0, &subs);
		for (unsigned s = 1; s <= subs; s++) {
			uint32_t v = 0;
			(void)co_od_get_u32(l->od, 0x1016, (uint8_t)s, &v);
			if (((v >> 16) & 0xFF) == n->id && (v & 0xFFFF)) {
				char np[JSON_PATH_MAX], pp[JSON_PATH_MAX];
				json_util_path_key(np, sizeof(np), path, "nodes");
				json_util_path_index(pp, sizeof(pp), np, i);
				json_util_path_key(np, sizeof(np), pp, "heartbeat_ms");
				return fail(c, np, "node %u is in heartbeat_consumers too", n->id);
			}
			if (!free_sub && !v)
				free_sub = (uint8_t)s;
		}
		if (!free_sub)
			return fail(c, path, "1016h is full");
		if ((rc = set_default(l->od, 0x1016, free_sub,
				      (uint32_t)n->id << 16 | n->heartbeat_ms)))
			return fail(c, path, "1016h:%u: %s", free_sub, strerror(-rc));
	}
	return 0;
}

/* "nodes": [{"id": N, "config": {...}}]. Node configurations are loaded
 * (files read, DCFs converted) here, so a broken one stops the start. */
static int parse_nodes(struct ctx *c, const cJSON *v, const char *path, cogw_line_config *l)
{
	const cJSON *it;
	size_t i = 0;
	int rc;

	if (!cJSON_IsArray(v))
		return fail(c, path, "expected an array of nodes, got %s", json_util_kind(v));
	if (cJSON_GetArraySize(v) > 127)
		return fail(c, path, "%d nodes, at most 127", cJSON_GetArraySize(v));
	l->nodes = calloc((size_t)cJSON_GetArraySize(v) + 1, sizeof(*l->nodes));
	if (!l->nodes)
		return -ENOMEM;
	cJSON_ArrayForEach(it, v)
	{
		char np[JSON_PATH_MAX], p[JSON_PATH_MAX];
		cogw_node *n = &l->nodes[i];
		const cJSON *x;
		uint64_t id;

		json_util_path_index(np, sizeof(np), path, i++);
		if ((rc = check_object(c, it, np, node_keys)) ||
		    (rc = json_util_require(it, "id", np, &x, c->msg, sizeof(c->msg))))
			return rc;
		json_util_path_key(p, sizeof(p), np, "id");
		if ((rc = json_util_uint(x, p, 1, 127, false, &id, c->msg, sizeof(c->msg))))
			return rc;
		if (id == l->node_id)
			return fail(c, p, "%llu is the line's own node_id", (unsigned long long)id);
		for (size_t j = 0; j < l->n_nodes; j++)
			if (l->nodes[j].id == id)
				return fail(c, p, "node %llu is already in %s[%zu]",
					    (unsigned long long)id, path, j);
		n->id = (uint8_t)id;
		l->n_nodes++;
		if ((rc = parse_node_manager(c, it, np, n)) ||
		    (rc = cogw_node_pdo_parse(it, np, l, c->base_dir, c->files, c->read, n, c->msg,
					      sizeof(c->msg))))
			return rc;
	}
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
	l->device_objects = (cogw_devobj_config){ .read_max_age_ms = 1000,
						  .write_update_ms = 10,
						  .watches = 64 };
}

static int parse_interface(struct ctx *c, const cJSON *o, const char *path, cogw_line_config *l)
{
	char p[JSON_PATH_MAX];
	const cJSON *v;
	int rc;

	if ((rc = json_util_require(o, "interface", path, &v, c->msg, sizeof(c->msg))))
		return rc;
	json_util_path_key(p, sizeof(p), path, "interface");
	if ((rc = json_util_string(v, p, 1, l->interface, IFNAME_MAX + 1, c->msg, sizeof(c->msg))))
		return rc;
	/* What the kernel's dev_valid_name() refuses. */
	if (!strcmp(l->interface, ".") || !strcmp(l->interface, "..") ||
	    strpbrk(l->interface, "/: \t\n"))
		return fail(c, p, "\"%s\" is not a valid interface name", l->interface);
	return 0;
}

static int parse_bitrate(struct ctx *c, const cJSON *o, const char *path, cogw_line_config *l)
{
	char p[JSON_PATH_MAX];
	const cJSON *v;
	uint64_t u;
	int rc;

	if ((rc = json_util_require(o, "bitrate", path, &v, c->msg, sizeof(c->msg))))
		return rc;
	json_util_path_key(p, sizeof(p), path, "bitrate");
	if ((rc = json_util_uint(v, p, 1, UINT32_MAX, false, &u, c->msg, sizeof(c->msg))))
		return rc;
	l->bitrate = 0;
	for (size_t i = 0; i < sizeof(cia_bitrates) / sizeof(cia_bitrates[0]); i++)
		if (u == cia_bitrates[i])
			l->bitrate = (uint32_t)u;
	if (!l->bitrate)
		return fail(c, p,
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

	json_util_path_key(p, sizeof(p), path, "rt");
	if ((rc = check_object(c, v, p, rt_keys)))
		return rc;
	s = l->rt.priority;
	if ((rc = json_util_opt_sint(v, "priority", p, 0, 99, &s, c->msg, sizeof(c->msg))))
		return rc;
	l->rt.priority = (int)s;
	s = l->rt.cpu;
	if ((rc = json_util_opt_sint(v, "cpu", p, -1, 1023, &s, c->msg, sizeof(c->msg))))
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

	if ((rc = json_util_opt_string(o, "name", path, 1, l->name, sizeof(l->name), c->msg,
				       sizeof(c->msg))))
		return rc;
	json_util_path_key(p, sizeof(p), path, "name");
	if ((rc = check_name_chars(c, p, l->name)) || (rc = parse_interface(c, o, path, l)) ||
	    (rc = parse_bitrate(c, o, path, l)))
		return rc;

	if ((rc = json_util_require(o, "node_id", path, &v, c->msg, sizeof(c->msg))))
		return rc;
	json_util_path_key(p, sizeof(p), path, "node_id");
	if ((rc = json_util_uint(v, p, 1, 127, false, &u, c->msg, sizeof(c->msg))))
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

	if ((rc = check_object(c, v, path, devobj_keys)) ||
	    (rc = opt_u32(c, v, "read_max_age_ms", path, 0, 86400000, &d->read_max_age_ms)) ||
	    (rc = opt_u32(c, v, "write_update_ms", path, 0, 60000, &d->write_update_ms)) ||
	    (rc = opt_u16(c, v, "watches", path, 1, 4096, &d->watches)))
		return rc;
	return 0;
}

/* heartbeat_consumers, device, nodes, manager and device_objects: each
 * parsed where present. */
static int parse_line_sections(struct ctx *c, const cJSON *o, const char *path, cogw_line_config *l,
			       co_od_std_opts *so, char *dev_name, char *hw, char *sw)
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
		if ((rc = parse_device(c, v, p, so, dev_name, hw, sw)))
			return rc;
	}
	v = json_util_get(o, "nodes");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "nodes");
		if ((rc = parse_nodes(c, v, p, l)))
			return rc;
	}
	v = json_util_get(o, "manager");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "manager");
		if ((rc = parse_manager(c, v, p, &l->manager)))
			return rc;
	}
	v = json_util_get(o, "device_objects");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "device_objects");
		if ((rc = parse_devobj(c, v, p, &l->device_objects)))
			return rc;
	}
	return 0;
}

static int parse_line(struct ctx *c, const cJSON *o, size_t idx, cogw_line_config *l)
{
	char path[JSON_PATH_MAX];
	char dev_name[CO_OD_STD_STRING_MAX + 1] = "cogw";
	char hw[CO_OD_STD_STRING_MAX + 1] = "", sw[CO_OD_STD_STRING_MAX + 1] = "";
	co_od_std_opts so;
	int rc;

	json_util_path_index(path, sizeof(path), "lines", idx);
	if ((rc = check_object(c, o, path, line_keys)))
		return rc;
	line_defaults(l, idx);
	if ((rc = parse_line_identity(c, o, path, l)))
		return rc;

	co_od_std_opts_init(&so);
	if ((rc = opt_u16(c, o, "network_id", path, 1, 127, &l->network_id)) ||
	    (rc = opt_u8(c, o, "sdo_servers", path, 1, 128, &l->sdo_servers)) ||
	    (rc = opt_u8(c, o, "sdo_clients", path, 0, 128, &l->sdo_clients)) ||
	    (rc = opt_u32(c, o, "sdo_timeout_ms", path, 1, 600000, &l->sdo_timeout_ms)) ||
	    (rc = opt_u32(c, o, "sdo_block_threshold", path, 1, UINT32_MAX,
			  &l->sdo_block_threshold)) ||
	    (rc = opt_u16(c, o, "heartbeat_ms", path, 0, 65535, &l->heartbeat_ms)) ||
	    (rc = opt_u32(c, o, "sync_period_us", path, 0, UINT32_MAX, &l->sync_period_us)) ||
	    (rc = opt_u32(c, o, "time_period_ms", path, 0, 86400000, &l->time_period_ms)) ||
	    (rc = opt_u32(c, o, "id_conflict_quiet_ms", path, 100, 3600000,
			  &l->id_conflict_quiet_ms)) ||
	    (rc = opt_u32(c, o, "fault_quiet_ms", path, 100, 3600000, &l->fault_quiet_ms)) ||
	    (rc = opt_u16(c, o, "rpdos", path, 0, 512, &so.rpdos)) ||
	    (rc = opt_u16(c, o, "tpdos", path, 0, 512, &so.tpdos)) ||
	    (rc = opt_u16(c, o, "pdo_scan_max", path, 1, CO_PDO_MAX, &l->pdo_scan_max)) ||
	    (rc = cogw_pdo_mode_parse(o, path, &l->pdo, c->msg, sizeof(c->msg))))
		return rc;
	if ((rc = parse_line_sections(c, o, path, l, &so, dev_name, hw, sw)) ||
	    (rc = cogw_line_pdo_check(l, path, c->msg, sizeof(c->msg))))
		return rc;

	so.device_name = dev_name;
	so.hw_version = hw;
	so.sw_version = sw;
	so.heartbeat_ms = l->heartbeat_ms;
	so.sync_period_us = l->sync_period_us;
	/* 1005h bit 30: we produce SYNC when a period is configured. */
	so.sync_cob_id = l->sync_period_us ? 0x40000080u : 0x80u;
	/* 1012h bit 30: we produce TIME when a period is configured. */
	so.time_cob_id = l->time_period_ms ? 0x40000100u : 0x100u;
	so.sdo_servers = l->sdo_servers;
	so.sdo_clients = l->sdo_clients;
	so.gateway = true;
	return build_od(c, o, path, l, &so);
}

static int check_unique(struct ctx *c, const cogw_config *cfg, size_t i)
{
	const cogw_line_config *l = &cfg->lines[i];
	char p[JSON_PATH_MAX];

	for (size_t j = 0; j < i; j++) {
		const cogw_line_config *o = &cfg->lines[j];

		if (!strcmp(o->name, l->name)) {
			snprintf(p, sizeof(p), "lines[%zu].name", i);
			return fail(c, p, "\"%s\" is already used by lines[%zu]", l->name, j);
		}
		if (!strcmp(o->interface, l->interface)) {
			snprintf(p, sizeof(p), "lines[%zu].interface", i);
			return fail(c, p, "\"%s\" is already used by lines[%zu]", l->interface, j);
		}
		if (o->network_id == l->network_id) {
			snprintf(p, sizeof(p), "lines[%zu].network_id", i);
			return fail(c, p, "%u is already used by lines[%zu]", l->network_id, j);
		}
	}
	return 0;
}

/* ---- top level ------------------------------------------------------------------ */

static void set_defaults(cogw_config *cfg, const char *source)
{
	memset(cfg, 0, sizeof(*cfg));
	snprintf(cfg->source, sizeof(cfg->source), "%s", source);
	snprintf(cfg->state_dir, sizeof(cfg->state_dir), "/var/lib/cogw");
	cfg->watchdog_check_ms = 500;
	cfg->file_memory = 64u << 20;
	snprintf(cfg->mailbox.instance, sizeof(cfg->mailbox.instance), "main");
	cfg->mailbox.depth = 64;
	cfg->mailbox.msg_size = 1024;
	cfg->mailbox.queue_mode = 0620;
	cfg->mailbox.max_clients = 16;
	cfg->mailbox.max_outstanding = 16; /* = mbx_server's defaults */
	cfg->mailbox.max_request_timeout_ms = 60000;
	cfg->mailbox.max_read_outstanding = 32;
	cfg->mailbox.transfer_slots = 2;
	cfg->mailbox.transfer_stall_ms = 5000;
	cfg->mailbox.transfer_lifetime_ms = 60000;
	cfg->mailbox.transfer_memory = 16u << 20;
	cfg->mailbox.lease_ms = 0;
	cfg->mailbox.max_transfer = 1u << 20;
	cfg->mailbox.default_access = COGW_ACCESS_WRITE;
}

static int parse_forwards(struct ctx *c, const cJSON *list, cogw_config *cfg);

static int parse_root(struct ctx *c, const cJSON *root, cogw_config *cfg)
{
	const cJSON *v, *it;
	int rc;

	if ((rc = check_object(c, root, "", top_keys)))
		return rc;
	v = json_util_get(root, "version");
	if (v) {
		uint64_t ver;

		if ((rc = json_util_uint(v, "version", 1, 1, false, &ver, c->msg, sizeof(c->msg))))
			return rc;
	}
	if ((rc = json_util_opt_string(root, "state_dir", "", 1, cfg->state_dir,
				       sizeof(cfg->state_dir), c->msg, sizeof(c->msg))) ||
	    (rc = json_util_opt_bool(root, "mlockall", "", &cfg->mlockall, c->msg,
				     sizeof(c->msg))) ||
	    (rc = opt_unsigned(c, root, "watchdog_check_ms", "", 10, 60000,
			       &cfg->watchdog_check_ms)) ||
	    (rc = opt_unsigned(c, root, "file_memory", "", 4096, UINT32_MAX, &cfg->file_memory)))
		return rc;
	cfg->files.limit = cfg->file_memory;
	v = json_util_get(root, "mailbox");
	if (v && (rc = parse_mailbox(c, v, &cfg->mailbox)))
		return rc;
	v = json_util_get(root, "debug");
	if (v) {
		if ((rc = check_object(c, v, "debug", debug_keys)) ||
		    (rc = json_util_opt_bool(v, "stall_signal", "debug", &cfg->debug_stall_signal,
					     c->msg, sizeof(c->msg))) ||
		    (rc = opt_unsigned(c, v, "stall_ms", "debug", 0, 3600000,
				       &cfg->debug_stall_ms)))
			return rc;
	}
	if ((rc = json_util_require(root, "lines", "", &v, c->msg, sizeof(c->msg))))
		return rc;
	if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) == 0)
		return fail(c, "lines", "expected a non-empty array, got %s",
			    cJSON_IsArray(v) ? "an empty array" : json_util_kind(v));
	if (cJSON_GetArraySize(v) > COGW_LINES_MAX)
		return fail(c, "lines", "%d lines, at most %d", cJSON_GetArraySize(v),
			    COGW_LINES_MAX);
	scan_networks(c, v);
	it = json_util_get(root, "gateway");
	if (it && (rc = parse_gateway(c, it)))
		return rc;
	cJSON_ArrayForEach(it, v)
	{
		size_t i = cfg->n_lines;

		/* Count the line first: cogw_config_free then frees its OD
		 * even when the line fails half-way. */
		cfg->n_lines++;
		if ((rc = parse_line(c, it, i, &cfg->lines[i])) || (rc = check_unique(c, cfg, i)))
			return rc;
	}
	it = json_util_get(root, "gateway");
	if (it && (v = json_util_get(it, "forward")) && (rc = parse_forwards(c, v, cfg)))
		return rc;
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

	if ((rc = check_object(c, o, path, dev_ref_keys)))
		return rc;
	json_util_path_key(p, sizeof(p), path, "line");
	if ((rc = json_util_require(o, "line", path, &v, c->msg, sizeof(c->msg))) ||
	    (rc = json_util_uint(v, p, 0, cfg->n_lines - 1, false, &x, c->msg, sizeof(c->msg))))
		return rc;
	r->line = (uint8_t)x;
	json_util_path_key(p, sizeof(p), path, "node");
	if ((rc = json_util_require(o, "node", path, &v, c->msg, sizeof(c->msg))) ||
	    (rc = json_util_uint(v, p, 1, 127, false, &x, c->msg, sizeof(c->msg))))
		return rc;
	r->node = (uint8_t)x;
	json_util_path_key(p, sizeof(p), path, "index");
	if ((rc = json_util_require(o, "index", path, &v, c->msg, sizeof(c->msg))) ||
	    (rc = json_od_parse_index(v, p, &r->index, c->msg, sizeof(c->msg))))
		return rc;
	json_util_path_key(p, sizeof(p), path, "sub");
	x = 0;
	if ((v = json_util_get(o, "sub")) &&
	    (rc = json_util_uint(v, p, 0, 255, false, &x, c->msg, sizeof(c->msg))))
		return rc;
	r->sub = (uint8_t)x;
	const cogw_line_config *l = &cfg->lines[r->line];
	for (size_t i = 0; i < l->n_nodes; i++)
		if (l->nodes[i].id == r->node) {
			if (l->nodes[i].pdo == COGW_PDO_AUTO)
				return 0;
			break;
		}
	return fail(c, path,
		    "node %u of line %u is not mirrored: forwarding needs it in that line's "
		    "\"nodes\" with \"pdo\": \"auto\" (docs/gateway.md)",
		    r->node, r->line);
}

/* gateway.forward, once the lines are built: each entry's image object
 * (UNSIGNED64, PDO-mappable) goes into every line's OD, like
 * gateway.process_image. */
static int parse_forwards(struct ctx *c, const cJSON *list, cogw_config *cfg)
{
	const cJSON *it;
	size_t i = 0;
	int rc;

	if (!cJSON_IsArray(list))
		return fail(c, "gateway.forward", "expected an array, got %s",
			    json_util_kind(list));
	if (cJSON_GetArraySize(list) > (int)COGW_FORWARDS_MAX)
		return fail(c, "gateway.forward", "%d entries, at most %u",
			    cJSON_GetArraySize(list), COGW_FORWARDS_MAX);
	cJSON_ArrayForEach(it, list)
	{
		char p[JSON_PATH_MAX], q[JSON_PATH_MAX];
		cogw_forward *f = &cfg->forwards[i];
		const cJSON *v;

		json_util_path_index(p, sizeof(p), "gateway.forward", i);
		if ((rc = check_object(c, it, p, forward_keys)))
			return rc;
		json_util_path_key(q, sizeof(q), p, "from");
		if ((rc = json_util_require(it, "from", p, &v, c->msg, sizeof(c->msg))) ||
		    (rc = parse_dev_ref(c, v, q, cfg, &f->from)))
			return rc;
		json_util_path_key(q, sizeof(q), p, "to");
		if ((rc = json_util_require(it, "to", p, &v, c->msg, sizeof(c->msg))) ||
		    (rc = parse_dev_ref(c, v, q, cfg, &f->to)))
			return rc;
		if (f->from.line == f->to.line)
			return fail(c, p, "from and to are on line %u: forwarding is between lines",
				    f->from.line);
		f->image = (uint16_t)(COGW_FORWARD_IMAGE_FIRST + i);
		json_util_path_key(q, sizeof(q), p, "image");
		if ((v = json_util_get(it, "image")) &&
		    (rc = json_od_parse_index(v, q, &f->image, c->msg, sizeof(c->msg))))
			return rc;
		if (!gw_image_in_range(f->image))
			return fail(c, q, "%04Xh is outside the process image B000h..BFFFh",
				    f->image);
		if (co_od_has_index(cfg->lines[0].od, f->image))
			return fail(c, q,
				    "%04Xh is already an object of the process image: give "
				    "another \"image\"",
				    f->image);
		for (size_t l = 0; l < cfg->n_lines; l++) {
			co_od_entry *e;
			rc = co_od_add_num(cfg->lines[l].od, f->image, 0, CO_T_UNSIGNED64,
					   CO_ACC_RW | CO_ACC_RPDO | CO_ACC_TPDO, 0, &e);
			if (rc)
				return fail(c, q, "cannot add %04Xh (%s)", f->image, strerror(-rc));
		}
		i++;
		cfg->n_forwards = i;
	}
	return 0;
}

int cogw_config_load_string(cogw_config *cfg, const char *json, const char *source_name, char *err,
			    size_t errlen)
{
	struct ctx c = { .source = source_name ? source_name : "<string>",
			 .err = err,
			 .errlen = errlen,
			 .read = &cfg->files };
	cJSON *root = NULL;
	int rc;

	set_defaults(cfg, c.source);
	/* files named in the config are relative to its directory */
	if (source_name && strrchr(source_name, '/'))
		snprintf(c.base_dir, sizeof(c.base_dir), "%.*s",
			 (int)(strrchr(source_name, '/') - source_name), source_name);
	if (source_name && !strcmp(source_name, COGW_DEFAULT_CONFIG_SOURCE))
		c.files = cogw_default_files;
	if (err && errlen)
		err[0] = '\0';
	rc = json_util_parse(json ? json : "", &root, c.msg, sizeof(c.msg));
	if (!rc)
		rc = parse_root(&c, root, cfg);
	cJSON_Delete(root);
	if (rc) {
		if (err && errlen) {
			if (rc == -ENOMEM)
				snprintf(err, errlen, "%s: out of memory", c.source);
			else
				snprintf(err, errlen, "%s: %s", c.source, c.msg);
		}
		cogw_config_free(cfg);
		snprintf(cfg->source, sizeof(cfg->source), "%s", c.source);
		return rc == -ENOMEM ? -ENOMEM : -EINVAL;
	}
	return 0;
}

int cogw_config_load_file(cogw_config *cfg, const char *path, char *err, size_t errlen)
{
	uint8_t *bytes;
	char *buf;
	size_t got;
	int rc;

	memset(cfg, 0, sizeof(*cfg));
	rc = cogw_file_read(path, CONFIG_FILE_MAX, &bytes, &got, err, errlen);
	if (rc)
		return rc == -EFBIG ? -EINVAL : rc;
	buf = (char *)bytes;
	if (strlen(buf) != got) {
		/* cJSON would stop at the NUL and miss the rest. */
		unsigned line = 1;

		for (const char *q = buf; *q; q++)
			line += *q == '\n';
		snprintf(err, errlen, "%s: line %u: NUL byte in file", path, line);
		free(buf);
		return -EINVAL;
	}
	rc = cogw_config_load_string(cfg, buf, path, err, errlen);
	free(buf);
	return rc;
}

void cogw_config_free(cogw_config *cfg)
{
	if (!cfg)
		return;
	for (size_t i = 0; i < COGW_LINES_MAX; i++) {
		cogw_line_config *l = &cfg->lines[i];

		co_od_destroy(l->od);
		l->od = NULL;
		for (size_t j = 0; l->nodes && j < l->n_nodes + 1; j++) {
			cogw_node_config_free(&l->nodes[j].config);
			cogw_node_pdo_free(&l->nodes[j]);
		}
		free(l->nodes);
		l->nodes = NULL;
	}
	cogw_file_set_free(&cfg->files);
	memset(cfg, 0, sizeof(*cfg));
}

/* ---- reload --------------------------------------------------------------------- */

static void note(char *what, size_t len, bool *changed, const char *name)
{
	size_t used;

	*changed = true;
	if (!what || !len)
		return;
	used = strlen(what);
	snprintf(what + used, len - used, "%s%s", used ? ", " : "", name);
}

static bool entry_same(const co_od_entry *a, const co_od_entry *b)
{
	if (a->index != b->index || a->sub != b->sub || a->type != b->type ||
	    a->access != b->access || a->max_size != b->max_size || a->obj_code != b->obj_code ||
	    a->has_limits != b->has_limits)
		return false;
	if (co_type_is_variable((co_type)a->type))
		return a->def_size == b->def_size &&
		       (!a->def_size || !memcmp(a->def_data, b->def_data, a->def_size));
	if (a->has_limits && (memcmp(a->min, b->min, a->size) || memcmp(a->max, b->max, a->size)))
		return false;
	return !memcmp(a->def, b->def, a->size);
}

/* Left out of the OD comparison: 1016h/1017h, which a reload may change,
 * and the node configuration objects, which "nodes" explains. */
static bool od_skip(uint16_t index)
{
	return index == 0x1016 || index == 0x1017 || index == CO_CFGMGR_IDX_CDCF ||
	       index == CO_CFGMGR_IDX_DATE || index == CO_CFGMGR_IDX_TIME;
}

/* The ODs agree apart from what od_skip() leaves out. */
static bool od_same(const co_od *a, const co_od *b)
{
	size_t i = 0, j = 0;

	for (;;) {
		const co_od_entry *ea = co_od_at(a, i), *eb = co_od_at(b, j);

		while (ea && od_skip(ea->index))
			ea = co_od_at(a, ++i);
		while (eb && od_skip(eb->index))
			eb = co_od_at(b, ++j);
		if (!ea || !eb)
			return !ea && !eb;
		if (!entry_same(ea, eb))
			return false;
		i++;
		j++;
	}
}

/* Same node ids and configurations, in the same order. */
static bool nodes_same(const cogw_line_config *a, const cogw_line_config *b)
{
	if (a->n_nodes != b->n_nodes)
		return false;
	for (size_t i = 0; i < a->n_nodes; i++)
		if (a->nodes[i].id != b->nodes[i].id ||
		    !cogw_node_config_equal(&a->nodes[i].config, &b->nodes[i].config) ||
		    a->nodes[i].assignment != b->nodes[i].assignment ||
		    memcmp(a->nodes[i].identity, b->nodes[i].identity,
			   sizeof(a->nodes[i].identity)) ||
		    a->nodes[i].heartbeat_ms != b->nodes[i].heartbeat_ms ||
		    a->nodes[i].keep_op != b->nodes[i].keep_op ||
		    a->nodes[i].target_state != b->nodes[i].target_state ||
		    !cogw_node_pdo_equal(&a->nodes[i], &b->nodes[i]))
			return false;
	return true;
}

bool cogw_config_reload_check(const cogw_config *cur, const cogw_config *next, char *what,
			      size_t whatlen)
{
	const cogw_mailbox_config *a = &cur->mailbox, *b = &next->mailbox;
	char name[64];
	bool changed = false;

	if (what && whatlen)
		what[0] = '\0';
#define DIFF(cond, label)                                     \
	do {                                                  \
		if (cond)                                     \
			note(what, whatlen, &changed, label); \
	} while (0)
	DIFF(strcmp(cur->state_dir, next->state_dir), "state_dir");
	DIFF(cur->mlockall != next->mlockall, "mlockall");
	DIFF(cur->watchdog_check_ms != next->watchdog_check_ms, "watchdog_check_ms");
	DIFF(cur->file_memory != next->file_memory, "file_memory");
	DIFF(cur->debug_stall_signal != next->debug_stall_signal ||
		     cur->debug_stall_ms != next->debug_stall_ms,
	     "debug");
	DIFF(strcmp(a->instance, b->instance), "mailbox.instance");
	DIFF(a->depth != b->depth, "mailbox.depth");
	DIFF(a->msg_size != b->msg_size, "mailbox.msg_size");
	DIFF(a->queue_mode != b->queue_mode, "mailbox.queue_mode");
	DIFF(a->max_clients != b->max_clients, "mailbox.max_clients");
	DIFF(a->max_transfer != b->max_transfer, "mailbox.max_transfer");
	DIFF(a->max_clients_per_uid != b->max_clients_per_uid, "mailbox.max_clients_per_uid");
	DIFF(a->max_outstanding != b->max_outstanding, "mailbox.max_outstanding");
	DIFF(a->max_request_timeout_ms != b->max_request_timeout_ms,
	     "mailbox.max_request_timeout_ms");
	DIFF(a->max_read_outstanding != b->max_read_outstanding, "mailbox.max_read_outstanding");
	DIFF(a->write_reserve != b->write_reserve, "mailbox.write_reserve");
	DIFF(a->transfer_slots != b->transfer_slots, "mailbox.transfer_slots");
	DIFF(a->max_transfers_per_client != b->max_transfers_per_client,
	     "mailbox.max_transfers_per_client");
	DIFF(a->transfer_stall_ms != b->transfer_stall_ms, "mailbox.transfer_stall_ms");
	DIFF(a->transfer_lifetime_ms != b->transfer_lifetime_ms, "mailbox.transfer_lifetime_ms");
	DIFF(a->transfer_memory != b->transfer_memory, "mailbox.transfer_memory");
	if (cur->n_lines != next->n_lines) {
		note(what, whatlen, &changed, "lines (count)");
	} else {
		for (size_t i = 0; i < cur->n_lines; i++) {
			const cogw_line_config *x = &cur->lines[i];
			const cogw_line_config *y = &next->lines[i];
			bool before = changed;

			changed = false;
#define LDIFF(cond, key)                                                       \
	do {                                                                   \
		if (cond) {                                                    \
			snprintf(name, sizeof(name), "lines[%zu].%s", i, key); \
			note(what, whatlen, &changed, name);                   \
		}                                                              \
	} while (0)
			LDIFF(strcmp(x->name, y->name), "name");
			LDIFF(strcmp(x->interface, y->interface), "interface");
			LDIFF(x->bitrate != y->bitrate, "bitrate");
			LDIFF(x->node_id != y->node_id, "node_id");
			LDIFF(x->network_id != y->network_id, "network_id");
			LDIFF(x->sdo_servers != y->sdo_servers, "sdo_servers");
			LDIFF(x->sdo_clients != y->sdo_clients, "sdo_clients");
			LDIFF(x->sdo_timeout_ms != y->sdo_timeout_ms, "sdo_timeout_ms");
			LDIFF(x->sdo_block_threshold != y->sdo_block_threshold,
			      "sdo_block_threshold");
			LDIFF(x->sync_period_us != y->sync_period_us, "sync_period_us");
			LDIFF(x->time_period_ms != y->time_period_ms, "time_period_ms");
			LDIFF(x->id_conflict_quiet_ms != y->id_conflict_quiet_ms,
			      "id_conflict_quiet_ms");
			LDIFF(x->fault_quiet_ms != y->fault_quiet_ms, "fault_quiet_ms");
			/* The OD follows from the keys above: name it only when
			 * they do not explain the difference. */
			LDIFF(!changed && x->od && y->od && !od_same(x->od, y->od),
			      "objects/values");
			LDIFF(!nodes_same(x, y), "nodes");
			LDIFF(x->pdo != y->pdo, "pdo");
			LDIFF(x->pdo_scan_max != y->pdo_scan_max, "pdo_scan_max");
			LDIFF(memcmp(&x->manager, &y->manager, sizeof(x->manager)), "manager");
			LDIFF(memcmp(&x->device_objects, &y->device_objects,
				     sizeof(x->device_objects)),
			      "device_objects");
			changed = changed || before;
#undef LDIFF
		}
	}
#undef DIFF
	return !changed;
}
