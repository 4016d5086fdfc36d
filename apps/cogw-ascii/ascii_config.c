/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-ascii/ascii_config.c - load and validate the gateway's JSON
 * file with the strict helpers cogwd's loader uses (apps/common/json_util.h).
 */
#include "apps/cogw-ascii/ascii_config.h"

#include <arpa/inet.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "apps/common/config.h"
#include "apps/common/json_util.h"

#define ASCII_CONFIG_FILE_MAX (64u * 1024u)

static const char *const top_keys[] = { "version",   "daemon_config", "unix_socket",
					"unix_mode", "tcp",           "limits",
					"session",   "route_line",    "comment",
					NULL };
static const char *const tcp_keys[] = { "address", "port", "access", "comment", NULL };
static const char *const limit_keys[] = {
	"max_connections", "max_line", "max_outstanding", "max_output", "request_timeout_ms",
	"comment",         NULL
};
static const char *const session_keys[] = { "network", "sdo_timeout_ms", "sdo_block", "comment",
					    NULL };

void ascii_config_defaults(ascii_config *c)
{
	memset(c, 0, sizeof *c);
	snprintf(c->unix_socket, sizeof c->unix_socket, "/run/cogw/ascii.sock");
	c->unix_mode = 0660;
	snprintf(c->tcp_address, sizeof c->tcp_address, "127.0.0.1");
	c->tcp_port = 4242;
	c->tcp_access = COGW_ACCESS_READ;
	c->max_connections = 64;
	c->max_line = 65536;
	c->max_outstanding = 4;
	c->max_output = 4u * 1024u * 1024u;
	c->sdo_timeout_ms = 1000;
	c->request_timeout_ms = 60000;
	c->default_network = -1;
}

static int access_of(const cJSON *v, const char *path, uint8_t *out, char *err, size_t errlen)
{
	char s[16];
	const json_at at = { path, err, errlen };

	if (json_util_string(v, &at, 1, s, sizeof s))
		return -EINVAL;
	if (strcmp(s, "none") == 0)
		*out = COGW_ACCESS_NONE;
	else if (strcmp(s, "read") == 0)
		*out = COGW_ACCESS_READ;
	else if (strcmp(s, "write") == 0)
		*out = COGW_ACCESS_WRITE;
	else
		return json_util_fail(err, errlen, path, "\"%s\" is not one of none, read, write",
				      s);
	return 0;
}

static int load_tcp(ascii_config *c, const cJSON *o, char *err, size_t errlen)
{
	const char *path = "tcp";
	char p[JSON_PATH_MAX];
	uint64_t u;
	const cJSON *v;
	unsigned char addr[16];
	const json_at at = { path, err, errlen };

	if (!cJSON_IsObject(o))
		return json_util_fail(err, errlen, path, "must be an object, not %s",
				      json_util_kind(o));
	if (json_util_check_object(o, &at, tcp_keys))
		return -EINVAL;
	c->tcp = true;
	if (json_util_opt_string(o, "address", &at, 1, c->tcp_address, sizeof c->tcp_address))
		return -EINVAL;
	if (inet_pton(AF_INET, c->tcp_address, addr) != 1 &&
	    inet_pton(AF_INET6, c->tcp_address, addr) != 1) {
		json_util_path_key(p, sizeof p, path, "address");
		return json_util_fail(err, errlen, p,
				      "\"%s\" is not a numeric IPv4 or IPv6 address",
				      c->tcp_address);
	}
	u = c->tcp_port;
	if (json_util_opt_uint(o, "port", &at, 1, 65535, &u))
		return -EINVAL;
	c->tcp_port = (uint16_t)u;
	v = json_util_get(o, "access");
	if (v) {
		json_util_path_key(p, sizeof p, path, "access");
		if (access_of(v, p, &c->tcp_access, err, errlen))
			return -EINVAL;
	}
	return 0;
}

static int load_limits(ascii_config *c, const cJSON *o, char *err, size_t errlen)
{
	const char *path = "limits";
	const json_at at = { path, err, errlen };

	if (!cJSON_IsObject(o))
		return json_util_fail(err, errlen, path, "must be an object, not %s",
				      json_util_kind(o));
	if (json_util_check_object(o, &at, limit_keys) ||
	    json_util_opt_unsigned(o, "max_connections", &at, 1, 4096, &c->max_connections) ||
	    json_util_opt_unsigned(o, "max_line", &at, 64, 16u * 1024u * 1024u, &c->max_line) ||
	    json_util_opt_unsigned(o, "max_outstanding", &at, 1, 64, &c->max_outstanding) ||
	    json_util_opt_unsigned(o, "max_output", &at, 4096, 256u * 1024u * 1024u,
				   &c->max_output) ||
	    json_util_opt_unsigned(o, "request_timeout_ms", &at, 100, 3600000,
				   &c->request_timeout_ms))
		return -EINVAL;
	return 0;
}

static int load_session(ascii_config *c, const cJSON *o, char *err, size_t errlen)
{
	const char *path = "session";
	int64_t net = c->default_network;
	const json_at at = { path, err, errlen };

	if (!cJSON_IsObject(o))
		return json_util_fail(err, errlen, path, "must be an object, not %s",
				      json_util_kind(o));
	if (json_util_check_object(o, &at, session_keys) ||
	    json_util_opt_sint(o, "network", &at, 0, 127, &net) ||
	    json_util_opt_unsigned(o, "sdo_timeout_ms", &at, 1, 600000, &c->sdo_timeout_ms) ||
	    json_util_opt_bool(o, "sdo_block", &at, &c->sdo_block))
		return -EINVAL;
	c->default_network = (int)net;
	return 0;
}

static int load_tree(ascii_config *c, const cJSON *root, char *err, size_t errlen)
{
	const cJSON *v;
	uint64_t u = 1;
	const json_at at = { "", err, errlen };
	const json_at at_unix_mode = { "unix_mode", err, errlen };

	if (!cJSON_IsObject(root))
		return json_util_fail(err, errlen, "(top)", "must be an object, not %s",
				      json_util_kind(root));
	if (json_util_check_object(root, &at, top_keys) ||
	    json_util_opt_uint(root, "version", &at, 1, 1, &u) ||
	    json_util_opt_string(root, "daemon_config", &at, 1, c->daemon_config,
				 sizeof c->daemon_config) ||
	    json_util_opt_string(root, "unix_socket", &at, 0, c->unix_socket,
				 sizeof c->unix_socket) ||
	    json_util_opt_unsigned(root, "route_line", &at, 0, COGW_LINES_MAX - 1, &c->route_line))
		return -EINVAL;
	v = json_util_get(root, "unix_mode");
	if (v) {
		if (!cJSON_IsString(v))
			return json_util_fail(err, errlen, "unix_mode",
					      "must be an octal string like \"0660\", not %s",
					      json_util_kind(v));
		if (json_util_uint(v, &at_unix_mode, 0, 0777, false, &u))
			return -EINVAL;
		if (u & 0007)
			return json_util_fail(err, errlen, "unix_mode",
					      "%s lets every local user connect, who could not "
					      "write the mailbox's command queues themselves: "
					      "use 0660 (a group) or 0600",
					      v->valuestring);
		c->unix_mode = (unsigned)u;
	}
	v = json_util_get(root, "tcp");
	if (v && load_tcp(c, v, err, errlen))
		return -EINVAL;
	v = json_util_get(root, "limits");
	if (v && load_limits(c, v, err, errlen))
		return -EINVAL;
	v = json_util_get(root, "session");
	if (v && load_session(c, v, err, errlen))
		return -EINVAL;
	return 0;
}

static int load_root(void *ctx, const cJSON *root, char *err, size_t errlen)
{
	return load_tree(ctx, root, err, errlen);
}

int ascii_config_load_string(ascii_config *c, const char *json, const char *source, char *err,
			     size_t errlen)
{
	ascii_config_defaults(c);
	return json_util_load_text(json, source, load_root, c, err, errlen);
}

int ascii_config_load_file(ascii_config *c, const char *path, char *err, size_t errlen)
{
	ascii_config_defaults(c);
	if (!path)
		return 0;
	return json_util_load_file(path, ASCII_CONFIG_FILE_MAX, load_root, c, err, errlen);
}
