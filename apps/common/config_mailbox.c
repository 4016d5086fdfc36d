/* SPDX-License-Identifier: MIT */
/*
 * apps/common/config_mailbox.c - the configuration's "mailbox" section:
 * the queue, its limits and the access rules (docs/config.md).
 */
#include <pwd.h>
#include <sys/stat.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "apps/common/config_read.h"
#include "apps/common/json_od.h"
#include "apps/common/json_util.h"

/* mirror mailbox/proto.h MBX_MSG_MIN / MBX_MSG_MAX */
#define MSG_SIZE_MIN 256u
#define MSG_SIZE_MAX 65535u

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
	return cfg_fail(c, path, "unknown access %s (one of none, read, write)", r);
}

/* ---- mailbox ------------------------------------------------------------------ */

static int parse_rule(struct ctx *c, const cJSON *o, const char *path, cogw_access_rule *r)
{
	char p[JSON_PATH_MAX];
	const cJSON *acc;
	int rc;
	const json_at at_path = cfg_at(c, path);

	if ((rc = cfg_check_object(c, o, path, rule_keys)))
		return rc;
	if ((rc = cfg_parse_uid(c, o, path, &r->uid)))
		return rc;
	if ((rc = json_util_require(o, "access", &at_path, &acc)))
		return rc;
	json_util_path_key(p, sizeof(p), path, "access");
	return parse_access_word(c, acc, p, &r->access);
}

int cfg_parse_uid(struct ctx *c, const cJSON *o, const char *path, uint32_t *out)
{
	char p[JSON_PATH_MAX];
	const cJSON *user = json_util_get(o, "user"), *uid = json_util_get(o, "uid");
	const json_at at = cfg_at(c, p);
	int rc;

	if (!user == !uid)
		return cfg_fail(c, path, "give either \"user\" or \"uid\"");
	if (user) {
		char name[256], buf[4096];
		struct passwd pw, *res = NULL;

		json_util_path_key(p, sizeof(p), path, "user");
		if ((rc = json_util_string(user, &at, 1, name, sizeof(name))))
			return rc;
		if (getpwnam_r(name, &pw, buf, sizeof(buf), &res) != 0 || !res)
			return cfg_fail(c, p, "unknown user \"%s\"", name);
		*out = res->pw_uid;
	} else {
		uint64_t u;

		json_util_path_key(p, sizeof(p), path, "uid");
		if ((rc = json_util_uint(uid, &at, 0, UINT32_MAX - 1, false, &u)))
			return rc;
		*out = (uint32_t)u;
	}
	return 0;
}

/* The per-user / per-client limits that depend on each other (ranges and
 * defaults: docs/config.md, docs/mailbox.md "Security model"). */
static int parse_mailbox_limits(struct ctx *c, const cJSON *o, cogw_mailbox_config *m)
{
	const char *path = "mailbox";
	char p[JSON_PATH_MAX];
	int rc;

	if ((rc = cfg_opt_unsigned(c, o, "max_read_outstanding", path, (cfg_range){ 1, 65535 },
				   &m->max_read_outstanding)) ||
	    (rc = cfg_opt_unsigned(c, o, "write_reserve", path, (cfg_range){ 1, 1023 },
				   &m->write_reserve)) ||
	    (rc = cfg_opt_unsigned(c, o, "transfer_slots", path, (cfg_range){ 1, 255 },
				   &m->transfer_slots)) ||
	    (rc = cfg_opt_unsigned(c, o, "max_transfers_per_client", path, (cfg_range){ 1, 255 },
				   &m->max_transfers_per_client)) ||
	    (rc = cfg_opt_unsigned(c, o, "transfer_stall_ms", path, (cfg_range){ 10, 600000u },
				   &m->transfer_stall_ms)) ||
	    (rc = cfg_opt_unsigned(c, o, "transfer_lifetime_ms", path,
				   (cfg_range){ 100, 86400000u }, &m->transfer_lifetime_ms)) ||
	    (rc = cfg_opt_unsigned(c, o, "transfer_memory", path, (cfg_range){ 4096, UINT32_MAX },
				   &m->transfer_memory)))
		return rc;
	/* A budget below max_transfer would refuse the largest transfer the
	 * configuration allows, every time. */
	if (m->transfer_memory < m->max_transfer) {
		json_util_path_key(p, sizeof(p), path, "transfer_memory");
		return cfg_fail(
			c, p, "%u is less than max_transfer (%u): no transfer that large could run",
			m->transfer_memory, m->max_transfer);
	}
	/* A reserve as large as the table would lock every read-only client
	 * out; 0 is not offered: one slot kept for writers is what makes a
	 * flood of read-only registrations harmless. */
	if (m->write_reserve && m->write_reserve >= m->max_clients) {
		json_util_path_key(p, sizeof(p), path, "write_reserve");
		return cfg_fail(c, p, "%u leaves read-only clients no slot (max_clients is %u)",
				m->write_reserve, m->max_clients);
	}
	if (m->max_transfers_per_client && m->max_transfers_per_client > m->transfer_slots) {
		json_util_path_key(p, sizeof(p), path, "max_transfers_per_client");
		return cfg_fail(c, p, "%u is more than transfer_slots (%u)",
				m->max_transfers_per_client, m->transfer_slots);
	}
	if (m->max_clients_per_uid > m->max_clients) {
		json_util_path_key(p, sizeof(p), path, "max_clients_per_uid");
		return cfg_fail(c, p, "%u is more than max_clients (%u)", m->max_clients_per_uid,
				m->max_clients);
	}
	return 0;
}

/* "queue_mode" (v, at p): an octal string. */
static int parse_queue_mode(struct ctx *c, const cJSON *v, const char *p, cogw_mailbox_config *m)
{
	uint64_t mode;
	int rc;
	const json_at at = cfg_at(c, p);

	/* A string, because JSON has no octal: 660 would be 01224. */
	if (!cJSON_IsString(v) || v->valuestring[0] != '0')
		return cfg_fail(c, p, "expected an octal string like \"0620\"");
	if ((rc = json_util_uint(v, &at, 0, 0777, false, &mode)))
		return rc;
	/* Every command carries its client's token: a command queue
	 * others can read gives them every client's rights. */
	if (mode & 0044)
		return cfg_fail(c, p,
				"clients could read other clients' tokens: "
				"no read bit for group or others (e.g. "
				"\"0620\" or \"0622\")");
	m->queue_mode = (unsigned)mode;
	return 0;
}

/* "rules" (v, at p): one per uid. */
static int parse_rules(struct ctx *c, const cJSON *v, const char *p, cogw_mailbox_config *m)
{
	const cJSON *it;
	char rp[JSON_PATH_MAX];
	int rc;

	if (!cJSON_IsArray(v))
		return cfg_fail(c, p, "expected an array, got %s", json_util_kind(v));
	if (cJSON_GetArraySize(v) > COGW_ACCESS_RULES_MAX)
		return cfg_fail(c, p, "%d rules, at most %d", cJSON_GetArraySize(v),
				COGW_ACCESS_RULES_MAX);
	cJSON_ArrayForEach(it, v)
	{
		cogw_access_rule *r = &m->rules[m->n_rules];

		json_util_path_index(rp, sizeof(rp), p, m->n_rules);
		if ((rc = parse_rule(c, it, rp, r)))
			return rc;
		for (size_t j = 0; j < m->n_rules; j++)
			if (m->rules[j].uid == r->uid)
				return cfg_fail(c, rp, "uid %u already has a rule (%s[%zu])",
						(unsigned)r->uid, p, j);
		m->n_rules++;
	}
	return 0;
}

/* The queue's name and size, and the number of clients and requests. */
static int parse_mailbox_queue(struct ctx *c, const cJSON *o, cogw_mailbox_config *m)
{
	const char *path = "mailbox";
	char p[JSON_PATH_MAX];
	int rc;
	const json_at at = cfg_at(c, path);

	if ((rc = json_util_opt_string(o, "instance", &at, 1, m->instance, sizeof(m->instance))))
		return rc;
	json_util_path_key(p, sizeof(p), path, "instance");
	if ((rc = cfg_check_name_chars(c, p, m->instance)) ||
	    (rc = cfg_opt_unsigned(c, o, "depth", path, (cfg_range){ 1, 65536 }, &m->depth)) ||
	    (rc = cfg_opt_unsigned(c, o, "msg_size", path,
				   (cfg_range){ MSG_SIZE_MIN, MSG_SIZE_MAX }, &m->msg_size)) ||
	    (rc = cfg_opt_unsigned(c, o, "max_clients", path, (cfg_range){ 1, 1024 },
				   &m->max_clients)) ||
	    (rc = cfg_opt_unsigned(c, o, "lease_ms", path, (cfg_range){ 0, 86400000u },
				   &m->lease_ms)) ||
	    (rc = cfg_opt_unsigned(c, o, "max_transfer", path, (cfg_range){ 1, 256u << 20 },
				   &m->max_transfer)) ||
	    (rc = cfg_opt_unsigned(c, o, "max_clients_per_uid", path, (cfg_range){ 1, 1024 },
				   &m->max_clients_per_uid)) ||
	    (rc = cfg_opt_unsigned(c, o, "max_outstanding", path, (cfg_range){ 1, 1024 },
				   &m->max_outstanding)) ||
	    (rc = cfg_opt_unsigned(c, o, "max_request_timeout_ms", path, (cfg_range){ 1, 3600000u },
				   &m->max_request_timeout_ms)))
		return rc;
	return 0;
}

int cfg_parse_mailbox(struct ctx *c, const cJSON *o, cogw_mailbox_config *m)
{
	const char *path = "mailbox";
	char p[JSON_PATH_MAX];
	const cJSON *v;
	int rc;

	if ((rc = cfg_check_object(c, o, path, mailbox_keys)) ||
	    (rc = parse_mailbox_queue(c, o, m)) || (rc = parse_mailbox_limits(c, o, m)))
		return rc;
	if ((v = json_util_get(o, "queue_mode"))) {
		json_util_path_key(p, sizeof(p), path, "queue_mode");
		if ((rc = parse_queue_mode(c, v, p, m)))
			return rc;
	}
	if ((v = json_util_get(o, "default_access"))) {
		json_util_path_key(p, sizeof(p), path, "default_access");
		if ((rc = parse_access_word(c, v, p, &m->default_access)))
			return rc;
	}
	if ((v = json_util_get(o, "rules"))) {
		json_util_path_key(p, sizeof(p), path, "rules");
		if ((rc = parse_rules(c, v, p, m)))
			return rc;
	}
	return 0;
}
