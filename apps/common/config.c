/* SPDX-License-Identifier: MIT */
/*
 * apps/common/config.c - cogwd's JSON configuration: parse, validate, build
 * each line's object dictionary (see config.h, docs/config.md). The top
 * level is read here; each section by its own reader, one table of keys
 * each, calling down only:
 *
 *   config.c          the file, the top-level keys, "debug"
 *   config_mailbox.c  "mailbox"
 *   config_gateway.c  "gateway": routes, process image, forwarding
 *   config_line.c     one of "lines" and its object dictionary
 *   config_nodes.c    a line's "nodes" and "manager"
 *   config_read.c     the typed readers they share (config_read.h)
 *   config_reload.c   what a reload may not change
 *
 * Validation is complete before the daemon touches anything: the first
 * error ends the load with one message "source: path: reason".
 */
#include "apps/common/config.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "apps/common/config_read.h"
#include "apps/common/file_read.h"
#include "apps/common/json_util.h"
#include "apps/common/pdo_config.h"

#define CONFIG_FILE_MAX (4u * 1024u * 1024u)

static const char *const top_keys[] = { "version", "state_dir",   "mlockall", "watchdog_check_ms",
					"mailbox", "file_memory", "lines",    "gateway",
					"debug",   "comment",     NULL };

static const char *const debug_keys[] = { "stall_signal", "stall_ms", "comment", NULL };

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

int cfg_parse_forwards(struct ctx *c, const cJSON *list, cogw_config *cfg);

/* "version", "state_dir", "mlockall", "watchdog_check_ms", "file_memory". */
static int parse_top_keys(struct ctx *c, const cJSON *root, cogw_config *cfg)
{
	const cJSON *v = json_util_get(root, "version");
	int rc;
	const json_at at = cfg_at(c, "version");
	const json_at at_root = cfg_at(c, "");

	if (v) {
		uint64_t ver;

		if ((rc = json_util_uint(v, &at, 1, 1, false, &ver)))
			return rc;
	}
	if ((rc = json_util_opt_string(root, "state_dir", &at_root, 1, cfg->state_dir,
				       sizeof(cfg->state_dir))) ||
	    (rc = json_util_opt_bool(root, "mlockall", &at_root, &cfg->mlockall)) ||
	    (rc = cfg_opt_unsigned(c, root, "watchdog_check_ms", "", (cfg_range){ 10, 60000 },
				   &cfg->watchdog_check_ms)) ||
	    (rc = cfg_opt_unsigned(c, root, "file_memory", "", (cfg_range){ 4096, UINT32_MAX },
				   &cfg->file_memory)))
		return rc;
	cfg->files.limit = cfg->file_memory;
	return 0;
}

/* "debug" (v). */
static int parse_debug(struct ctx *c, const cJSON *v, cogw_config *cfg)
{
	int rc;
	const json_at at = cfg_at(c, "debug");

	if ((rc = cfg_check_object(c, v, "debug", debug_keys)) ||
	    (rc = json_util_opt_bool(v, "stall_signal", &at, &cfg->debug_stall_signal)) ||
	    (rc = cfg_opt_unsigned(c, v, "stall_ms", "debug", (cfg_range){ 0, 3600000 },
				   &cfg->debug_stall_ms)))
		return rc;
	return 0;
}

/* "lines" (v) is a list of 1..COGW_LINES_MAX. */
static int check_lines(struct ctx *c, const cJSON *v)
{
	if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) == 0)
		return cfg_fail(c, "lines", "expected a non-empty array, got %s",
				cJSON_IsArray(v) ? "an empty array" : json_util_kind(v));
	if (cJSON_GetArraySize(v) > COGW_LINES_MAX)
		return cfg_fail(c, "lines", "%d lines, at most %d", cJSON_GetArraySize(v),
				COGW_LINES_MAX);
	return 0;
}

/* Each of "lines" (v), after the gateway's routes are known. */
static int parse_lines(struct ctx *c, const cJSON *v, cogw_config *cfg)
{
	const cJSON *it;
	int rc;

	cJSON_ArrayForEach(it, v)
	{
		size_t i = cfg->n_lines;

		/* Count the line first: cogw_config_free then frees its OD
		 * even when the line fails half-way. */
		cfg->n_lines++;
		if ((rc = cfg_parse_line(c, it, i, &cfg->lines[i])) ||
		    (rc = cfg_check_unique(c, cfg, i)))
			return rc;
	}
	return 0;
}

static int parse_root(struct ctx *c, const cJSON *root, cogw_config *cfg)
{
	const cJSON *v, *gw = json_util_get(root, "gateway"), *lines;
	int rc;
	const json_at at = cfg_at(c, "");

	if ((rc = cfg_check_object(c, root, "", top_keys)) || (rc = parse_top_keys(c, root, cfg)))
		return rc;
	v = json_util_get(root, "mailbox");
	if (v && (rc = cfg_parse_mailbox(c, v, &cfg->mailbox)))
		return rc;
	v = json_util_get(root, "debug");
	if (v && (rc = parse_debug(c, v, cfg)))
		return rc;
	if ((rc = json_util_require(root, "lines", &at, &lines)) || (rc = check_lines(c, lines)))
		return rc;
	cfg_scan_networks(c, lines);
	if ((gw && (rc = cfg_parse_gateway(c, gw))) || (rc = parse_lines(c, lines, cfg)))
		return rc;
	if (gw && (v = json_util_get(gw, "forward")) && (rc = cfg_parse_forwards(c, v, cfg)))
		return rc;
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
		cogw_unknown_config_free(&l->unknown);
	}
	cogw_file_set_free(&cfg->files);
	memset(cfg, 0, sizeof(*cfg));
}
