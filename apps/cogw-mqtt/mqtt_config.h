/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-mqtt/mqtt_config.h - the MQTT bridge's own configuration (a
 * JSON file, reference in docs/mqtt.md "Configuration"), validated strictly
 * like cogwd's (apps/common/config.c): unknown keys, wrong types and values
 * out of range are refused with one message "file: json.path: reason" and
 * the bridge does not start.
 */
#ifndef COGW_MQTT_CONFIG_H
#define COGW_MQTT_CONFIG_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define MQTT_NAME_MAX 65    /* gateway name, client id: 64 bytes */
#define MQTT_PREFIX_MAX 129 /* topic prefix: 128 bytes */
#define MQTT_PATH_MAX 256
#define MQTT_WATCH_MAX 64 /* watches of one bridge, configured and requested */

struct ascii_type;

/* A watched device object (docs/mqtt.md "Process values"). */
typedef struct mqtt_watch_cfg {
	uint16_t net;
	uint8_t node;
	uint8_t sub;
	uint16_t index;
	uint32_t min_interval_ms;
	const struct ascii_type *type; /* how the value is shown */
} mqtt_watch_cfg;

/* What a request may do (docs/mqtt.md "Roles"). */
typedef enum mqtt_role {
	MQTT_ROLE_NONE = 0,  /* every request refused */
	MQTT_ROLE_READ = 1,  /* SDO reads, watch add/remove */
	MQTT_ROLE_WRITE = 2, /* also SDO writes and NMT commands */
} mqtt_role;

typedef struct mqtt_config {
	char daemon_config[MQTT_PATH_MAX]; /* cogwd's file; "" = its embedded default */
	char gateway[MQTT_NAME_MAX];       /* the gateway's name in topics */
	char topic_prefix[MQTT_PREFIX_MAX];
	uint8_t role;        /* mqtt_role */
	unsigned route_line; /* line asked for networks not attached (0) */
	/* broker */
	char host[256];
	uint16_t port;
	bool tls; /* mqtts:// */
	char client_id[MQTT_NAME_MAX];
	int protocol; /* 5 or 4 (MQTT 3.1.1) */
	unsigned keepalive_s;
	int qos;
	char ca_file[MQTT_PATH_MAX], cert_file[MQTT_PATH_MAX], key_file[MQTT_PATH_MAX];
	char credentials_file[MQTT_PATH_MAX];
	unsigned reconnect_min_ms, reconnect_max_ms;
	/* publish */
	bool pub_nmt, pub_boot, pub_emcy, pub_heartbeat, pub_manager;
	unsigned counters_period_s; /* 0 = never */
	unsigned emcy_history;      /* EMCYs kept per node in .../emcy/history */
	/* offline queue */
	unsigned queue_messages, queue_bytes;
	/* requests */
	unsigned max_payload, max_inflight, requests_per_s, request_timeout_ms;
	/* process values watched from the start */
	mqtt_watch_cfg watch[MQTT_WATCH_MAX];
	unsigned n_watch;
} mqtt_config;

void mqtt_config_defaults(mqtt_config *c);
/* Load path (NULL = defaults only). 0, or -EINVAL/-ENOENT/-EIO with one
 * line in err. */
int mqtt_config_load_file(mqtt_config *c, const char *path, char *err, size_t errlen);
int mqtt_config_load_string(mqtt_config *c, const char *json, const char *source, char *err,
			    size_t errlen);
/* The user name and password of credentials_file ("user:password", one
 * line; the file must not be readable by others). 0 or -1 with err. */
int mqtt_config_credentials(const mqtt_config *c, char *user, size_t ucap, char *pass, size_t pcap,
			    char *err, size_t errlen);
const char *mqtt_role_to_string(uint8_t role);

#endif /* COGW_MQTT_CONFIG_H */
