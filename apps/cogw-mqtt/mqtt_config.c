/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-mqtt/mqtt_config.c - load and validate the bridge's JSON file
 * with the strict helpers cogwd's loader uses (apps/common/json_util.h).
 */
#include "apps/cogw-mqtt/mqtt_config.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "apps/cogw-ascii/ascii_value.h"
#include "apps/common/config.h"
#include "apps/common/file_read.h"
#include "apps/common/json_util.h"

#define MQTT_CONFIG_FILE_MAX (64u * 1024u)

static const char *const top_keys[] = { "version", "daemon_config", "gateway", "topic_prefix",
					"role",    "route_line",    "broker",  "publish",
					"queue",   "requests",      "watch",   "comment",
					NULL };
static const char *const broker_keys[] = { "uri",
					   "client_id",
					   "protocol",
					   "keepalive_s",
					   "qos",
					   "ca_file",
					   "cert_file",
					   "key_file",
					   "credentials_file",
					   "reconnect_min_ms",
					   "reconnect_max_ms",
					   "comment",
					   NULL };
static const char *const publish_keys[] = { "nmt",          "boot",    "emcy",
					    "heartbeat",    "manager", "counters_period_s",
					    "emcy_history", "comment", NULL };
static const char *const queue_keys[] = { "max_messages", "max_bytes", "comment", NULL };
static const char *const watch_keys[] = { "net",     "node", "index",
					  "sub",     "type", "min_interval_ms",
					  "comment", NULL };
static const char *const request_keys[] = { "max_payload", "max_inflight", "per_second",
					    "timeout_ms",  "comment",      NULL };

const char *mqtt_role_to_string(uint8_t role)
{
	return role == MQTT_ROLE_WRITE ? "write" : role == MQTT_ROLE_READ ? "read" : "none";
}

void mqtt_config_defaults(mqtt_config *c)
{
	memset(c, 0, sizeof *c);
	snprintf(c->gateway, sizeof c->gateway, "gateway");
	snprintf(c->topic_prefix, sizeof c->topic_prefix, "cogw");
	c->role = MQTT_ROLE_READ;
	snprintf(c->host, sizeof c->host, "127.0.0.1");
	c->port = 1883;
	c->protocol = 5;
	c->keepalive_s = 30;
	c->qos = 1;
	c->reconnect_min_ms = 500;
	c->reconnect_max_ms = 30000;
	c->pub_nmt = c->pub_boot = c->pub_emcy = c->pub_heartbeat = c->pub_manager = true;
	c->counters_period_s = 60;
	c->emcy_history = 8;
	c->queue_messages = 1000;
	c->queue_bytes = 1024u * 1024u;
	c->max_payload = 4096;
	c->max_inflight = 8;
	c->requests_per_s = 50;
	c->request_timeout_ms = 10000;
}

/* A topic level: no MQTT wildcard, no separator, no control character. */
static bool topic_level_ok(const char *s, bool allow_slash)
{
	if (!*s)
		return false;
	for (const char *p = s; *p; p++) {
		unsigned char ch = (unsigned char)*p;

		if (ch < 0x20 || ch == 0x7F || ch == '+' || ch == '#' ||
		    (ch == '/' && !allow_slash))
			return false;
	}
	return !allow_slash || (s[0] != '/' && s[strlen(s) - 1] != '/' && !strstr(s, "//"));
}

/* The host of uri at *p ("[v6]" or a name of letters, digits, '.' and
 * '-') into c->host; *p moved past it. */
static int uri_host(mqtt_config *c, const char *uri, const char **p, char *err, size_t errlen)
{
	const char *host = *p, *end;
	size_t n;

	if (**p == '[') {
		end = strchr(*p, ']');
		if (!end)
			return json_util_fail(err, errlen, "broker.uri", "\"%s\": no closing ']'",
					      uri);
		host = *p + 1;
		n = (size_t)(end - host);
		*p = end + 1;
	} else {
		while (**p && **p != ':' && **p != '/')
			(*p)++;
		n = (size_t)(*p - host);
		for (size_t i = 0; i < n; i++) {
			char ch = host[i];

			if (!((ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
			      (ch >= '0' && ch <= '9') || ch == '.' || ch == '-'))
				return json_util_fail(err, errlen, "broker.uri",
						      "\"%s\": the host has a '%c'", uri, ch);
		}
	}
	if (n == 0 || n >= sizeof c->host)
		return json_util_fail(err, errlen, "broker.uri", "\"%s\": no host, or too long",
				      uri);
	memcpy(c->host, host, n);
	c->host[n] = 0;
	return 0;
}

/* mqtt://host[:port] or mqtts://host[:port]; host a name, an IPv4 address
 * or [an IPv6 address]. */
static int parse_uri(mqtt_config *c, const char *uri, char *err, size_t errlen)
{
	const char *p = uri;

	if (strncmp(p, "mqtt://", 7) == 0) {
		c->tls = false;
		c->port = 1883;
		p += 7;
	} else if (strncmp(p, "mqtts://", 8) == 0) {
		c->tls = true;
		c->port = 8883;
		p += 8;
	} else {
		return json_util_fail(err, errlen, "broker.uri",
				      "\"%s\" must start with mqtt:// or mqtts://", uri);
	}
	if (uri_host(c, uri, &p, err, errlen))
		return -EINVAL;
	if (*p == ':') {
		char *e;
		unsigned long port = strtoul(p + 1, &e, 10);

		if (e == p + 1 || port < 1 || port > 65535 || (*e && strcmp(e, "/") != 0))
			return json_util_fail(err, errlen, "broker.uri",
					      "\"%s\": the port must be 1..65535", uri);
		c->port = (uint16_t)port;
	} else if (*p && strcmp(p, "/") != 0) {
		return json_util_fail(err, errlen, "broker.uri", "\"%s\": unexpected \"%s\"", uri,
				      p);
	}
	return 0;
}

static int readable_file(const char *path, const char *file, char *err, size_t errlen)
{
	struct stat st;

	if (!*file)
		return 0;
	if (stat(file, &st) < 0 || !S_ISREG(st.st_mode))
		return json_util_fail(err, errlen, path, "\"%s\" is not a readable regular file",
				      file);
	return 0;
}

/* "broker.uri" and "broker.protocol" as given, before they are read. */
#define BROKER_URI_MAX 300
#define BROKER_PROTO_MAX 8

/* "broker"'s keys into c (uri and proto as given), before they are
 * checked together. */
static int read_broker_keys(mqtt_config *c, const cJSON *o, char *uri, char *proto, char *err,
			    size_t errlen)
{
	const char *path = "broker";
	uint64_t qos = (uint64_t)c->qos;
	const json_at at = { path, err, errlen };

	if (json_util_check_object(o, &at, broker_keys) ||
	    json_util_opt_string(o, "uri", &at, 1, uri, BROKER_URI_MAX) ||
	    json_util_opt_string(o, "client_id", &at, 1, c->client_id, sizeof c->client_id) ||
	    json_util_opt_string(o, "protocol", &at, 1, proto, BROKER_PROTO_MAX) ||
	    json_util_opt_unsigned(o, "keepalive_s", &at, 5, 3600, &c->keepalive_s) ||
	    json_util_opt_uint(o, "qos", &at, 0, 2, &qos) ||
	    json_util_opt_string(o, "ca_file", &at, 1, c->ca_file, sizeof c->ca_file) ||
	    json_util_opt_string(o, "cert_file", &at, 1, c->cert_file, sizeof c->cert_file) ||
	    json_util_opt_string(o, "key_file", &at, 1, c->key_file, sizeof c->key_file) ||
	    json_util_opt_string(o, "credentials_file", &at, 1, c->credentials_file,
				 sizeof c->credentials_file) ||
	    json_util_opt_unsigned(o, "reconnect_min_ms", &at, 100, 600000, &c->reconnect_min_ms) ||
	    json_util_opt_unsigned(o, "reconnect_max_ms", &at, 100, 3600000, &c->reconnect_max_ms))
		return -EINVAL;
	c->qos = (int)qos;
	return 0;
}

/* TLS: the files go with an mqtts:// uri, and they can be read. */
static int check_broker_files(const mqtt_config *c, char *err, size_t errlen)
{
	if ((c->ca_file[0] || c->cert_file[0] || c->key_file[0]) && !c->tls)
		return json_util_fail(err, errlen, "broker",
				      "TLS files are given but the uri is not mqtts://");
	if (c->tls && !c->ca_file[0])
		return json_util_fail(err, errlen, "broker.ca_file",
				      "mqtts:// needs the CA that signed the broker's certificate");
	if (!c->cert_file[0] != !c->key_file[0])
		return json_util_fail(err, errlen, "broker",
				      "a client certificate needs both cert_file and key_file");
	if (readable_file("broker.ca_file", c->ca_file, err, errlen) ||
	    readable_file("broker.cert_file", c->cert_file, err, errlen) ||
	    readable_file("broker.key_file", c->key_file, err, errlen) ||
	    readable_file("broker.credentials_file", c->credentials_file, err, errlen))
		return -EINVAL;
	return 0;
}

static int load_broker(mqtt_config *c, const cJSON *o, char *err, size_t errlen)
{
	char uri[BROKER_URI_MAX] = "", proto[BROKER_PROTO_MAX] = "";

	if (!cJSON_IsObject(o))
		return json_util_fail(err, errlen, "broker", "must be an object, not %s",
				      json_util_kind(o));
	if (read_broker_keys(c, o, uri, proto, err, errlen))
		return -EINVAL;
	if (uri[0] && parse_uri(c, uri, err, errlen))
		return -EINVAL;
	if (proto[0]) {
		if (strcmp(proto, "5") == 0)
			c->protocol = 5;
		else if (strcmp(proto, "3.1.1") == 0)
			c->protocol = 4;
		else
			return json_util_fail(err, errlen, "broker.protocol",
					      "\"%s\" is not one of \"5\", \"3.1.1\"", proto);
	}
	if (c->client_id[0] && !topic_level_ok(c->client_id, false))
		return json_util_fail(err, errlen, "broker.client_id",
				      "\"%s\" has a control character, '+', '#' or '/'",
				      c->client_id);
	if (c->reconnect_max_ms < c->reconnect_min_ms)
		return json_util_fail(err, errlen, "broker.reconnect_max_ms",
				      "%u is below reconnect_min_ms %u", c->reconnect_max_ms,
				      c->reconnect_min_ms);
	return check_broker_files(c, err, errlen);
}

static int load_publish(mqtt_config *c, const cJSON *o, char *err, size_t errlen)
{
	const char *path = "publish";
	const json_at at = { path, err, errlen };

	if (!cJSON_IsObject(o))
		return json_util_fail(err, errlen, path, "must be an object, not %s",
				      json_util_kind(o));
	if (json_util_check_object(o, &at, publish_keys) ||
	    json_util_opt_bool(o, "nmt", &at, &c->pub_nmt) ||
	    json_util_opt_bool(o, "boot", &at, &c->pub_boot) ||
	    json_util_opt_bool(o, "emcy", &at, &c->pub_emcy) ||
	    json_util_opt_bool(o, "heartbeat", &at, &c->pub_heartbeat) ||
	    json_util_opt_bool(o, "manager", &at, &c->pub_manager) ||
	    json_util_opt_unsigned(o, "counters_period_s", &at, 0, 86400, &c->counters_period_s) ||
	    json_util_opt_unsigned(o, "emcy_history", &at, 0, 16, &c->emcy_history))
		return -EINVAL;
	if (c->counters_period_s && c->counters_period_s < 1)
		return json_util_fail(err, errlen, "publish.counters_period_s", "must be >= 1");
	return 0;
}

static int load_section(const cJSON *root, const char *key,
			int (*load)(mqtt_config *, const cJSON *, char *, size_t), mqtt_config *c,
			char *err, size_t errlen)
{
	const cJSON *v = json_util_get(root, key);

	return v ? load(c, v, err, errlen) : 0;
}

static int load_queue(mqtt_config *c, const cJSON *o, char *err, size_t errlen)
{
	const char *path = "queue";
	const json_at at = { path, err, errlen };

	if (!cJSON_IsObject(o))
		return json_util_fail(err, errlen, path, "must be an object, not %s",
				      json_util_kind(o));
	if (json_util_check_object(o, &at, queue_keys) ||
	    json_util_opt_unsigned(o, "max_messages", &at, 1, 1000000, &c->queue_messages) ||
	    json_util_opt_unsigned(o, "max_bytes", &at, 1024, 1024u * 1024u * 1024u,
				   &c->queue_bytes))
		return -EINVAL;
	return 0;
}

static int load_requests(mqtt_config *c, const cJSON *o, char *err, size_t errlen)
{
	const char *path = "requests";
	const json_at at = { path, err, errlen };

	if (!cJSON_IsObject(o))
		return json_util_fail(err, errlen, path, "must be an object, not %s",
				      json_util_kind(o));
	if (json_util_check_object(o, &at, request_keys) ||
	    json_util_opt_unsigned(o, "max_payload", &at, 256, 1024u * 1024u, &c->max_payload) ||
	    json_util_opt_unsigned(o, "max_inflight", &at, 1, 64, &c->max_inflight) ||
	    json_util_opt_unsigned(o, "per_second", &at, 1, 10000, &c->requests_per_s) ||
	    json_util_opt_unsigned(o, "timeout_ms", &at, 100, 600000, &c->request_timeout_ms))
		return -EINVAL;
	return 0;
}

static int load_watch_entry(mqtt_watch_cfg *w, const cJSON *o, const char *path, char *err,
			    size_t errlen)
{
	static const char *const keys[] = { "net", "node", "index", "sub" };
	static const uint64_t mins[] = { 1, 1, 0, 0 }, maxs[] = { 127, 127, 0xFFFF, 255 };
	uint64_t got[4], interval = 1000;
	const cJSON *v;
	char kw[8], p[JSON_PATH_MAX];
	const json_at at = { path, err, errlen };
	const json_at at_p = { p, err, errlen };

	if (!cJSON_IsObject(o))
		return json_util_fail(err, errlen, path, "must be an object, not %s",
				      json_util_kind(o));
	if (json_util_check_object(o, &at, watch_keys))
		return -EINVAL;
	for (size_t i = 0; i < 4; i++) {
		json_util_path_key(p, sizeof p, path, keys[i]);
		if (json_util_require(o, keys[i], &at, &v) ||
		    json_util_uint(v, &at_p, mins[i], maxs[i], i == 2, &got[i]))
			return -EINVAL;
	}
	json_util_path_key(p, sizeof p, path, "type");
	if (json_util_require(o, "type", &at, &v) || json_util_string(v, &at_p, 1, kw, sizeof kw))
		return -EINVAL;
	w->type = ascii_type_find(kw, strlen(kw));
	if (!w->type)
		return json_util_fail(err, errlen, p, "\"%s\" is not a CiA 309-3 type keyword", kw);
	if (json_util_opt_uint(o, "min_interval_ms", &at, 0, 3600000, &interval))
		return -EINVAL;
	w->net = (uint16_t)got[0];
	w->node = (uint8_t)got[1];
	w->index = (uint16_t)got[2];
	w->sub = (uint8_t)got[3];
	w->min_interval_ms = (uint32_t)interval;
	return 0;
}

static int load_watch(mqtt_config *c, const cJSON *a, char *err, size_t errlen)
{
	char p[JSON_PATH_MAX];
	size_t i = 0;

	if (!cJSON_IsArray(a))
		return json_util_fail(err, errlen, "watch", "must be an array, not %s",
				      json_util_kind(a));
	for (const cJSON *o = a->child; o; o = o->next, i++) {
		json_util_path_index(p, sizeof p, "watch", i);
		if (i >= MQTT_WATCH_MAX)
			return json_util_fail(err, errlen, p, "more than %d watches",
					      MQTT_WATCH_MAX);
		if (load_watch_entry(&c->watch[i], o, p, err, errlen))
			return -EINVAL;
	}
	c->n_watch = (unsigned)i;
	return 0;
}

/* "role": none, read or write (-1: none of them). */
static int role_of(const char *name, uint8_t *role)
{
	static const struct {
		const char *name;
		mqtt_role role;
	} roles[] = { { "none", MQTT_ROLE_NONE },
		      { "read", MQTT_ROLE_READ },
		      { "write", MQTT_ROLE_WRITE } };

	for (size_t i = 0; i < sizeof roles / sizeof roles[0]; i++)
		if (strcmp(name, roles[i].name) == 0) {
			*role = (uint8_t)roles[i].role;
			return 0;
		}
	return -1;
}

static int load_tree(mqtt_config *c, const cJSON *root, char *err, size_t errlen)
{
	char role[8] = "";
	uint64_t u = 1;
	const json_at at = { "", err, errlen };

	if (!cJSON_IsObject(root))
		return json_util_fail(err, errlen, "(top)", "must be an object, not %s",
				      json_util_kind(root));
	if (json_util_check_object(root, &at, top_keys) ||
	    json_util_opt_uint(root, "version", &at, 1, 1, &u) ||
	    json_util_opt_string(root, "daemon_config", &at, 1, c->daemon_config,
				 sizeof c->daemon_config) ||
	    json_util_opt_string(root, "gateway", &at, 1, c->gateway, sizeof c->gateway) ||
	    json_util_opt_string(root, "topic_prefix", &at, 1, c->topic_prefix,
				 sizeof c->topic_prefix) ||
	    json_util_opt_string(root, "role", &at, 1, role, sizeof role) ||
	    json_util_opt_unsigned(root, "route_line", &at, 0, COGW_LINES_MAX - 1, &c->route_line))
		return -EINVAL;
	if (!topic_level_ok(c->gateway, false))
		return json_util_fail(err, errlen, "gateway",
				      "\"%s\" must be one topic level: no '/', '+', '#' or "
				      "control character",
				      c->gateway);
	if (!topic_level_ok(c->topic_prefix, true) || c->topic_prefix[0] == '$')
		return json_util_fail(err, errlen, "topic_prefix",
				      "\"%s\" must be topic levels without '+', '#', '//', a "
				      "leading '$' or '/' or a trailing '/'",
				      c->topic_prefix);
	if (role[0] && role_of(role, &c->role))
		return json_util_fail(err, errlen, "role", "\"%s\" is not one of none, read, write",
				      role);
	if (load_section(root, "broker", load_broker, c, err, errlen) ||
	    load_section(root, "publish", load_publish, c, err, errlen) ||
	    load_section(root, "queue", load_queue, c, err, errlen) ||
	    load_section(root, "requests", load_requests, c, err, errlen) ||
	    load_section(root, "watch", load_watch, c, err, errlen))
		return -EINVAL;
	if (!c->client_id[0])
		snprintf(c->client_id, sizeof c->client_id, "cogw-%.58s", c->gateway);
	return 0;
}

static int load_root(void *ctx, const cJSON *root, char *err, size_t errlen)
{
	return load_tree(ctx, root, err, errlen);
}

int mqtt_config_load_string(mqtt_config *c, const char *json, const char *source, char *err,
			    size_t errlen)
{
	mqtt_config_defaults(c);
	return json_util_load_text(json, source, load_root, c, err, errlen);
}

int mqtt_config_load_file(mqtt_config *c, const char *path, char *err, size_t errlen)
{
	mqtt_config_defaults(c);
	if (!path)
		return 0;
	return json_util_load_file(path, MQTT_CONFIG_FILE_MAX, load_root, c, err, errlen);
}

int mqtt_config_credentials(const mqtt_config *c, char *user, size_t ucap, char *pass, size_t pcap,
			    char *err, size_t errlen)
{
	struct stat st;
	uint8_t *buf;
	size_t len;
	char *colon, *nl;

	user[0] = pass[0] = 0;
	if (!c->credentials_file[0])
		return 0;
	if (stat(c->credentials_file, &st) < 0 || (st.st_mode & 0007)) {
		snprintf(err, errlen, "%s: missing, or readable by every local user (chmod o-rwx)",
			 c->credentials_file);
		return -1;
	}
	if (cogw_file_read(c->credentials_file, 4096, &buf, &len, err, errlen))
		return -1;
	nl = strchr((char *)buf, '\n');
	if (nl)
		*nl = 0;
	colon = strchr((char *)buf, ':');
	if (!colon || colon == (char *)buf || (size_t)(colon - (char *)buf) >= ucap ||
	    strlen(colon + 1) >= pcap) {
		snprintf(err, errlen, "%s: the first line must be user:password",
			 c->credentials_file);
		free(buf);
		return -1;
	}
	*colon = 0;
	snprintf(user, ucap, "%s", (char *)buf);
	snprintf(pass, pcap, "%s", colon + 1);
	memset(buf, 0, len);
	free(buf);
	return 0;
}
