/* SPDX-License-Identifier: MIT */
/*
 * apps/common/config_read.h - what the configuration's section readers
 * share (config.c and the config_*.c below it): the load's context and
 * the small typed readers of config_read.c. Internal to apps/common.
 *
 * Every reader returns 0, -ENOMEM, or -EINVAL with "path: reason" in
 * c->msg; the first error ends the load.
 */
#ifndef COGW_APPS_CONFIG_READ_H
#define COGW_APPS_CONFIG_READ_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <cjson/cJSON.h>

#include "apps/common/config.h"
#include "apps/common/file_read.h"
#include "apps/common/json_util.h"
#include "apps/common/node_config.h"
#include "core/od.h"
#include "gateway/route.h"

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

/* ---- the typed readers (config_read.c) ---- */

/* The json_util readers' place at path, their message going to c->msg
 * (path may still be filled in later: only the pointer is kept). */
static inline json_at cfg_at(struct ctx *c, const char *path)
{
	return (json_at){ path, c->msg, sizeof(c->msg) };
}

/* "path: reason" into c->msg; returns -EINVAL. */
int cfg_fail(struct ctx *c, const char *path, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

/* The bounds of a number key, both included. */
typedef struct cfg_range {
	uint64_t min, max;
} cfg_range;

/* An optional number key of o (at path) in range r into *out, which holds
 * the default. */
int cfg_opt_u32(struct ctx *c, const cJSON *o, const char *key, const char *path, cfg_range r,
		uint32_t *out);
int cfg_opt_u16(struct ctx *c, const cJSON *o, const char *key, const char *path, cfg_range r,
		uint16_t *out);
int cfg_opt_u8(struct ctx *c, const cJSON *o, const char *key, const char *path, cfg_range r,
	       uint8_t *out);
int cfg_opt_unsigned(struct ctx *c, const cJSON *o, const char *key, const char *path, cfg_range r,
		     unsigned *out);
/* A flag: its bit, and whether it is set when the key is not given. */
typedef struct cfg_flag {
	uint32_t bit;
	bool def;
} cfg_flag;

/* An optional boolean key: f.bit set in *bits when it is (or defaults to)
 * true. */
int cfg_opt_flag(struct ctx *c, const cJSON *o, const char *key, const char *path, cfg_flag f,
		 uint32_t *bits);
/* An UNSIGNED32 given as a number or a "0x..." string. */
int cfg_opt_u32_hex(struct ctx *c, const cJSON *o, const char *key, const char *path,
		    uint32_t *out);
/* o has only the keys of the NULL-terminated list keys. */
int cfg_check_object(struct ctx *c, const cJSON *o, const char *path, const char *const *keys);
/* Names that end up in queue names and logs: [A-Za-z0-9_-]. */
int cfg_check_name_chars(struct ctx *c, const char *path, const char *s);

/* ---- "mailbox" (config_mailbox.c) ---- */

int cfg_parse_mailbox(struct ctx *c, const cJSON *o, cogw_mailbox_config *m);

/* ---- "gateway" (config_gateway.c) ---- */

/* Each line's network, before anything is built (1F2Ch defaults). */
void cfg_scan_networks(struct ctx *c, const cJSON *lines);
int cfg_parse_gateway(struct ctx *c, const cJSON *o);
/* "gateway.forward", after the lines. */
int cfg_parse_forwards(struct ctx *c, const cJSON *list, cogw_config *cfg);
/* A line's 1F2Ch routes and process image objects. */
int cfg_gateway_objects(struct ctx *c, cogw_line_config *l);
/* "objects" may not define the process image's objects. */
int cfg_refuse_image_objects(struct ctx *c, const cJSON *objects, const char *path);
/* While "values" are applied, 1F2Ch writes are checked as the gateway
 * checks them (on), then no longer (off). */
void cfg_route_checks(struct ctx *c, co_od *od, bool on);
int cfg_check_attached_routes(struct ctx *c, const char *path, const co_od *od);

/* ---- one of "lines" (config_line.c) ---- */

int cfg_parse_line(struct ctx *c, const cJSON *o, size_t idx, cogw_line_config *l);
/* Line i's name, interface and network differ from the lines before. */
int cfg_check_unique(struct ctx *c, const cogw_config *cfg, size_t i);

/* ---- a line's "nodes" and "manager" (config_nodes.c) ---- */

int cfg_parse_nodes(struct ctx *c, const cJSON *v, const char *path, cogw_line_config *l);
/* {"user": NAME} (resolved now) or {"uid": N} of object o (config_mailbox.c). */
int cfg_parse_uid(struct ctx *c, const cJSON *o, const char *path, uint32_t *uid);
/* A line's "app": objects clients own (config_app.c) and the application
 * watchdog's keys (config_appwd.c); after its objects. */
int cfg_parse_app(struct ctx *c, const cJSON *v, const char *path, cogw_line_config *l);
int cfg_parse_manager(struct ctx *c, const cJSON *o, const char *path, cogw_manager_config *m);
/* The manager's objects (1F80h, 1F81h, ...) in the line's OD. */
int cfg_manager_objects(struct ctx *c, const char *path, cogw_line_config *l);

/* ---- config_appwd.c: the application watchdog's keys of a line's "app",
 * which cfg_parse_app checked (after its OD is built) ---- */
int cfg_parse_appwd(struct ctx *c, const cJSON *o, const char *path, cogw_line_config *l);
/* ---- a line's "unknown_nodes" (config_unknown.c) ---- */

/* After "manager" (the boot policy needs it). */
int cfg_parse_unknown(struct ctx *c, const cJSON *o, const char *path, cogw_line_config *l);
/* The boot policy's device files, and 1F22h:n for the node-IDs it may
 * adopt; after the nodes' objects. */
int cfg_unknown_objects(struct ctx *c, const char *path, cogw_line_config *l);

#endif /* COGW_APPS_CONFIG_READ_H */
