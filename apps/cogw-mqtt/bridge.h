/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-mqtt/bridge.h - cogw-mqtt, the MQTT bridge: one mailbox client
 * of cogwd (libcogw) and one MQTT client (libmosquitto), driven by one
 * epoll loop in one thread (docs/mqtt.md). It never touches CAN and never
 * waits on the daemon: requests go out with cogw_send_async() and their
 * answers come back through cogw_recv(), so a slow broker or a slow device
 * only fills the bridge's own bounded queue.
 *
 *   main.c         command line, configuration, the loop
 *   mqtt_events.c  mailbox events -> topics (state, EMCY, boot, counters)
 *   mqtt_serve.c   requests from the broker -> mailbox commands -> replies
 *   mqtt_watch.c   process values (docs/mqtt.md "Process values")
 *   mqtt_link.c    the broker: connect, backoff, birth/will, the offline queue
 *   bridge.c       clocks, requests under way, values as JSON
 *
 * Calls go down only (tests/checks/check_callgraph): main.c ->
 * mqtt_events.c, mqtt_serve.c -> mqtt_watch.c -> mqtt_link.c -> bridge.c;
 * the link reaches the files above it through the link_hooks main.c gives
 * it.
 */
#ifndef COGW_MQTT_BRIDGE_H
#define COGW_MQTT_BRIDGE_H

#include <mosquitto.h>
#include <mqtt_protocol.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "apps/cogw-mqtt/mqtt_config.h"
#include "apps/cogw-mqtt/mqtt_request.h"
#include "apps/common/config.h"
#include "mailbox/cogw.h"

/* One message waiting for the broker. */
typedef struct out_msg {
	struct out_msg *next;
	char *topic;
	void *payload;
	size_t len;
	bool retain;
	mosquitto_property *props; /* reply: correlation data */
} out_msg;

/* A request under way in the daemon (answer by corr). */
typedef struct pending {
	bool used;
	bool internal; /* the bridge's own: node table, counters */
	uint64_t corr;
	uint16_t cmd;
	uint8_t line;
	uint64_t deadline_ms;
	mqtt_request req;     /* the request as decoded (not internal) */
	mqtt_watch_cfg watch; /* a DEV_WATCH/UNWATCH: its object */
	char *reply_topic;    /* where the reply goes */
	mosquitto_property *reply_props;
} pending;

/* A watch the daemon confirmed, on `line`. */
typedef struct bridge_watch {
	uint8_t line;
	mqtt_watch_cfg w;
} bridge_watch;

/* What the bridge knows of one node (republished on every connect). */
typedef struct node_state {
	uint8_t nmt; /* NMT state byte, 0xFF unknown */
	uint8_t hb;  /* 0 not monitored, 1 active, 2 lost */
	bool known;
	char *boot_json; /* last boot step, retained */
	unsigned n_emcy, emcy_head;
	struct {
		uint64_t time_ms; /* wall clock */
		uint16_t code;
		uint8_t reg;
		uint8_t msef[5];
	} emcy[16];
} node_state;

/* What the bridge knows of one line's CiA 302-2 manager (republished on
 * every connect, asked for at every subscription and counters period). */
typedef struct manager_state {
	bool known;
	uint8_t state; /* co_mgr_state */
	uint8_t flags; /* CO_MGR_F_* */
} manager_state;

/* A bus health fault of a line as last published (retained at
 * health/<fault>): the episode that runs, the counters. */
typedef struct fault_state {
	bool known;
	mbx_ev_comm_fault last;
} fault_state;

typedef struct bridge_stats {
	uint64_t published, queued, dropped, dropped_bytes, connects, connect_failures, disconnects;
	uint64_t events, events_lost; /* mailbox events, and lost before us */
	uint64_t values;              /* process values published */
	uint64_t requests, replies_ok, refused_role, malformed, too_big, bad_field, unknown_op,
		rate_limited, busy, unsupported, failed, timed_out, mbx_errors;
} bridge_stats;

typedef struct bridge bridge;

/* What the broker link calls up (mqtt_link.c takes them at link_init):
 * the broker accepted the connection (republish the retained state), a
 * request arrived on the request topic. */
typedef struct link_hooks {
	void (*on_connect)(bridge *b);
	void (*on_message)(bridge *b, const struct mosquitto_message *msg,
			   const mosquitto_property *props);
} link_hooks;

struct bridge {
	mqtt_config cfg;
	cogw_config daemon;
	char daemon_config_path[MQTT_PATH_MAX];
	int verbose;
	cogw *h;
	struct mosquitto *mosq;
	int epfd, sigfd;
	bool stopping;
	/* broker link */
	link_hooks link_up;
	bool connected;     /* CONNACK accepted */
	bool connecting;    /* a connect is under way */
	bool tried_connect; /* libmosquitto knows the broker's address */
	int reg_fd;         /* the mosquitto socket registered with epfd */
	uint32_t reg_events;
	unsigned backoff_ms;
	uint64_t next_connect_ms;
	unsigned unacked; /* QoS 1/2 publishes not acknowledged yet */
	out_msg *q_head, *q_tail;
	size_t q_len, q_bytes;
	char topic_status[MQTT_PREFIX_MAX + MQTT_NAME_MAX + 16];
	char topic_request[MQTT_PREFIX_MAX + MQTT_NAME_MAX + 16];
	char topic_response[MQTT_PREFIX_MAX + MQTT_NAME_MAX + 16];
	/* mailbox */
	uint32_t subscribed[COGW_LINES_MAX];
	uint64_t next_subscribe_ms, next_counters_ms, next_table_ms;
	pending *pend; /* cfg.max_inflight + internal slots */
	size_t n_pend;
	/* request flood control: a token bucket */
	double tokens;
	uint64_t tokens_ms;
	node_state *nodes; /* [line * 128 + node] */
	manager_state managers[COGW_LINES_MAX];
	fault_state faults[COGW_LINES_MAX][MBX_FAULT_COUNT];
	bridge_watch watch[MQTT_WATCH_MAX];
	size_t n_watch;
	bool cfg_watch_removed[MQTT_WATCH_MAX];  /* by a watch_remove request */
	int cfg_watch_status[MQTT_WATCH_MAX];    /* the last answer, logged when it changes */
	bool cfg_watch_answered[MQTT_WATCH_MAX]; /* its arming was answered once */
	bridge_stats st;
};

/* bridge.c */
uint64_t bridge_now_ms(void);  /* CLOCK_MONOTONIC */
uint64_t bridge_wall_ms(void); /* CLOCK_REALTIME */
/* ISO 8601 UTC with milliseconds: "2026-11-26T20:15:01.123Z", of a wall
 * clock time or of now. */
void bridge_time_of(uint64_t wall_ms, char *buf, size_t n);
void bridge_time_text(char *buf, size_t n);
int bridge_line_of_net(const bridge *b, uint16_t net); /* -1 if not attached */

/* A request to the daemon through the loop handle (never waits: a full
 * command queue is COGW_E_WOULDBLOCK). 0 or a cogw_err. */
int bridge_send(bridge *b, unsigned line, uint16_t cmd, const void *payload, size_t len,
		uint64_t *corr);
/* The bridge's own mailbox request: the slot it took, or NULL (counted). */
pending *bridge_send_internal(bridge *b, unsigned line, uint16_t cmd, const void *payload,
			      size_t len);
pending *bridge_pending_of(bridge *b, uint64_t corr);
void bridge_pending_release(pending *p);
/* A value's bytes as JSON of its type: a number where JSON carries it
 * exactly, else a string; NULL with err when the bytes do not fit it. */
struct cJSON *bridge_value_json(const ascii_type *t, const uint8_t *data, size_t len, char *err,
				size_t errlen);

/* mqtt_link.c */
int link_init(bridge *b, const link_hooks *up);
void link_free(bridge *b);
/* Publish now if the broker is there, else queue (oldest dropped and
 * counted when the queue is full). Takes ownership of payload and props. */
void link_publish(bridge *b, const char *topic, char *payload, size_t len, bool retain,
		  mosquitto_property *props);
/* Publish a cJSON object (deleted here). */
struct cJSON;
void link_publish_json(bridge *b, const char *topic, struct cJSON *o, bool retain,
		       mosquitto_property *props);
void link_service(bridge *b, uint32_t epoll_events); /* socket ready or timer */
void link_sync_epoll(bridge *b);
uint64_t link_next_deadline(const bridge *b);
void link_stop(bridge *b); /* graceful "offline", disconnect */

/* mqtt_events.c */
void events_on_connect(bridge *b); /* republish the retained state */
void events_service(bridge *b);    /* subscriptions, periodic counters */
void events_on_event(bridge *b, const cogw_msg *m);
void events_on_internal(bridge *b, pending *p, const cogw_msg *m);
void events_free(bridge *b);

/* mqtt_serve.c */
void serve_on_message(bridge *b, const struct mosquitto_message *msg,
		      const mosquitto_property *props);
void serve_on_response(bridge *b, pending *p, const cogw_msg *m);
void serve_expire(bridge *b); /* requests past their deadline */

#endif /* COGW_MQTT_BRIDGE_H */
