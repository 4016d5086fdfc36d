/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-mqtt/mqtt_link.c - the broker side of the bridge: libmosquitto
 * driven from the bridge's epoll loop (no library thread), connect and
 * reconnect with exponential backoff, the retained birth "online" and the
 * last will "offline" (docs/mqtt.md "Liveness"), and the bounded offline
 * queue with its drop counters (docs/mqtt.md "While the broker is away").
 */
#include <cjson/cJSON.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>

#include "apps/cogw-mqtt/bridge.h"

/* Publishes handed to libmosquitto and not yet sent/acknowledged: above
 * this the bridge keeps messages in its own bounded queue, so that a
 * stalled broker connection never grows libmosquitto's unbounded one. */
#define LINK_WINDOW 256u
#define EPOLL_TAG_MQTT 2u

static void schedule_reconnect(bridge *b)
{
	uint64_t now = bridge_now_ms();

	b->connected = b->connecting = false;
	b->unacked = 0;
	b->reg_fd = -1; /* the socket is closed: whatever number comes next, add it again */
	if (!b->backoff_ms)
		b->backoff_ms = b->cfg.reconnect_min_ms;
	b->next_connect_ms = now + b->backoff_ms;
	b->backoff_ms = b->backoff_ms * 2 > b->cfg.reconnect_max_ms ? b->cfg.reconnect_max_ms
								    : b->backoff_ms * 2;
}

static char *status_payload(const char *state, const char *reason, bool with_time)
{
	cJSON *o = cJSON_CreateObject();
	char t[40], *s;

	cJSON_AddStringToObject(o, "state", state);
	if (reason)
		cJSON_AddStringToObject(o, "reason", reason);
	if (with_time) {
		bridge_time_text(t, sizeof t);
		cJSON_AddStringToObject(o, "time", t);
	}
	s = cJSON_PrintUnformatted(o);
	cJSON_Delete(o);
	return s;
}

static int publish_now(bridge *b, const out_msg *m)
{
	int mid;
	int rc = mosquitto_publish_v5(b->mosq, &mid, m->topic, (int)m->len, m->payload, b->cfg.qos,
				      m->retain, m->props);

	if (rc == MOSQ_ERR_SUCCESS) {
		b->st.published++;
		b->unacked++;
	}
	return rc;
}

static void msg_free(out_msg *m)
{
	free(m->topic);
	free(m->payload);
	mosquitto_property_free_all(&m->props);
	free(m);
}

static void flush_queue(bridge *b)
{
	while (b->q_head && b->connected && b->unacked < LINK_WINDOW) {
		out_msg *m = b->q_head;

		if (publish_now(b, m) != MOSQ_ERR_SUCCESS)
			return;
		b->q_head = m->next;
		if (!b->q_head)
			b->q_tail = NULL;
		b->q_len--;
		b->q_bytes -= m->len;
		msg_free(m);
	}
}

static void enqueue(bridge *b, out_msg *m)
{
	if (b->q_tail)
		b->q_tail->next = m;
	else
		b->q_head = m;
	b->q_tail = m;
	b->q_len++;
	b->q_bytes += m->len;
	b->st.queued++;
	/* the oldest go first: what is newest describes the present */
	while (b->q_head && (b->q_len > b->cfg.queue_messages || b->q_bytes > b->cfg.queue_bytes)) {
		out_msg *old = b->q_head;

		b->q_head = old->next;
		if (!b->q_head)
			b->q_tail = NULL;
		b->q_len--;
		b->q_bytes -= old->len;
		b->st.dropped++;
		b->st.dropped_bytes += old->len;
		msg_free(old);
	}
}

void link_publish(bridge *b, const char *topic, char *payload, size_t len, bool retain,
		  mosquitto_property *props)
{
	out_msg *m = calloc(1, sizeof *m);

	if (!m || !payload || !(m->topic = strdup(topic))) {
		free(m);
		free(payload);
		mosquitto_property_free_all(&props);
		b->st.dropped++;
		return;
	}
	m->payload = payload;
	m->len = len;
	m->retain = retain;
	m->props = props;
	if (b->connected && !b->q_head && b->unacked < LINK_WINDOW &&
	    publish_now(b, m) == MOSQ_ERR_SUCCESS) {
		msg_free(m);
		return;
	}
	enqueue(b, m);
}

void link_publish_json(bridge *b, const char *topic, cJSON *o, bool retain,
		       mosquitto_property *props)
{
	char *s = o ? cJSON_PrintUnformatted(o) : NULL;

	cJSON_Delete(o);
	link_publish(b, topic, s, s ? strlen(s) : 0, retain, props);
}

static void on_connect(struct mosquitto *mosq, void *obj, int rc, int flags,
		       const mosquitto_property *props)
{
	bridge *b = obj;
	char *birth;

	(void)flags;
	(void)props;
	b->connecting = false;
	if (rc != 0) {
		b->st.connect_failures++;
		fprintf(stderr, "cogw-mqtt: broker %s:%u refused the connection: %s\n", b->cfg.host,
			b->cfg.port,
			b->cfg.protocol == 5 ? mosquitto_reason_string(rc)
					     : mosquitto_connack_string(rc));
		mosquitto_disconnect(mosq);
		schedule_reconnect(b);
		return;
	}
	b->connected = true;
	b->backoff_ms = 0;
	b->st.connects++;
	fprintf(stderr, "cogw-mqtt: connected to %s:%u as %s (MQTT %s)\n", b->cfg.host, b->cfg.port,
		b->cfg.client_id, b->cfg.protocol == 5 ? "5" : "3.1.1");
	mosquitto_subscribe_v5(mosq, NULL, b->topic_request, 1, 0, NULL);
	birth = status_payload("online", NULL, true);
	if (birth)
		mosquitto_publish_v5(mosq, NULL, b->topic_status, (int)strlen(birth), birth, 1,
				     true, NULL);
	free(birth);
	/* what waited first, then the present state over it (retained topics
	 * end with the newest) */
	flush_queue(b);
	b->link_up.on_connect(b);
}

static void on_disconnect(struct mosquitto *mosq, void *obj, int rc,
			  const mosquitto_property *props)
{
	bridge *b = obj;

	(void)mosq;
	(void)props;
	if (b->connected) {
		b->st.disconnects++;
		fprintf(stderr, "cogw-mqtt: lost the broker (%s); %zu message(s) queued\n",
			rc ? mosquitto_strerror(rc) : "disconnected", b->q_len);
	}
	if (!b->stopping)
		schedule_reconnect(b);
}

static void on_publish(struct mosquitto *mosq, void *obj, int mid, int rc,
		       const mosquitto_property *props)
{
	bridge *b = obj;

	(void)mosq;
	(void)mid;
	(void)rc;
	(void)props;
	if (b->unacked)
		b->unacked--;
	flush_queue(b);
}

static void on_message(struct mosquitto *mosq, void *obj, const struct mosquitto_message *msg,
		       const mosquitto_property *props)
{
	bridge *b = obj;

	(void)mosq;
	b->link_up.on_message(b, msg, props);
}

static void on_log(struct mosquitto *mosq, void *obj, int level, const char *str)
{
	bridge *b = obj;

	(void)mosq;
	if ((level & (MOSQ_LOG_ERR | MOSQ_LOG_WARNING)) || b->verbose > 1)
		fprintf(stderr, "cogw-mqtt: libmosquitto: %s\n", str);
}

int link_init(bridge *b, const link_hooks *up)
{
	char user[256], pass[256], err[512], *will;
	int rc;

	b->link_up = *up;
	snprintf(b->topic_status, sizeof b->topic_status, "%s/%s/status", b->cfg.topic_prefix,
		 b->cfg.gateway);
	snprintf(b->topic_request, sizeof b->topic_request, "%s/%s/request", b->cfg.topic_prefix,
		 b->cfg.gateway);
	snprintf(b->topic_response, sizeof b->topic_response, "%s/%s/response", b->cfg.topic_prefix,
		 b->cfg.gateway);
	b->reg_fd = -1;
	mosquitto_lib_init();
	b->mosq = mosquitto_new(b->cfg.client_id, true, b);
	if (!b->mosq) {
		fprintf(stderr, "cogw-mqtt: mosquitto_new: %s\n", strerror(errno));
		return -1;
	}
	mosquitto_int_option(b->mosq, MOSQ_OPT_PROTOCOL_VERSION,
			     b->cfg.protocol == 5 ? MQTT_PROTOCOL_V5 : MQTT_PROTOCOL_V311);
	mosquitto_connect_v5_callback_set(b->mosq, on_connect);
	mosquitto_disconnect_v5_callback_set(b->mosq, on_disconnect);
	mosquitto_publish_v5_callback_set(b->mosq, on_publish);
	mosquitto_message_v5_callback_set(b->mosq, on_message);
	mosquitto_log_callback_set(b->mosq, on_log);
	will = status_payload("offline", "connection lost", false);
	rc = mosquitto_will_set_v5(b->mosq, b->topic_status, (int)strlen(will), will, 1, true,
				   NULL);
	free(will);
	if (rc) {
		fprintf(stderr, "cogw-mqtt: last will: %s\n", mosquitto_strerror(rc));
		return -1;
	}
	if (mqtt_config_credentials(&b->cfg, user, sizeof user, pass, sizeof pass, err,
				    sizeof err)) {
		fprintf(stderr, "cogw-mqtt: credentials: %s\n", err);
		return -1;
	}
	if (user[0] && (rc = mosquitto_username_pw_set(b->mosq, user, pass))) {
		fprintf(stderr, "cogw-mqtt: credentials: %s\n", mosquitto_strerror(rc));
		return -1;
	}
	memset(pass, 0, sizeof pass);
	if (b->cfg.tls) {
		rc = mosquitto_tls_set(b->mosq, b->cfg.ca_file, NULL,
				       b->cfg.cert_file[0] ? b->cfg.cert_file : NULL,
				       b->cfg.key_file[0] ? b->cfg.key_file : NULL, NULL);
		if (rc) {
			fprintf(stderr, "cogw-mqtt: TLS files: %s\n", mosquitto_strerror(rc));
			return -1;
		}
	}
	b->next_connect_ms = 0;
	return 0;
}

static void try_connect(bridge *b)
{
	int rc;

	/* the first call gives libmosquitto the broker's address */
	if (!b->tried_connect)
		rc = mosquitto_connect_async(b->mosq, b->cfg.host, b->cfg.port,
					     (int)b->cfg.keepalive_s);
	else
		rc = mosquitto_reconnect_async(b->mosq);
	b->tried_connect = true;
	if (rc != MOSQ_ERR_SUCCESS) {
		b->st.connect_failures++;
		if (b->verbose || b->st.connect_failures == 1)
			fprintf(stderr, "cogw-mqtt: cannot connect to %s:%u: %s\n", b->cfg.host,
				b->cfg.port,
				rc == MOSQ_ERR_ERRNO ? strerror(errno) : mosquitto_strerror(rc));
		schedule_reconnect(b);
		return;
	}
	b->connecting = true;
	b->reg_fd = -1;
	/* a broker that accepts TCP but never answers CONNECT */
	b->next_connect_ms = bridge_now_ms() + 1000ull * b->cfg.keepalive_s;
}

void link_sync_epoll(bridge *b)
{
	int fd = mosquitto_socket(b->mosq);
	uint32_t events = EPOLLIN | (mosquitto_want_write(b->mosq) ? EPOLLOUT : 0);

	if (fd == b->reg_fd && events == b->reg_events)
		return;
	if (b->reg_fd >= 0)
		epoll_ctl(b->epfd, EPOLL_CTL_DEL, b->reg_fd, NULL);
	b->reg_fd = -1;
	if (fd >= 0) {
		struct epoll_event ev = { .events = events, .data.u32 = EPOLL_TAG_MQTT };

		if (epoll_ctl(b->epfd, EPOLL_CTL_ADD, fd, &ev) == 0 ||
		    (errno == EEXIST && epoll_ctl(b->epfd, EPOLL_CTL_MOD, fd, &ev) == 0)) {
			b->reg_fd = fd;
			b->reg_events = events;
		}
	}
}

/* The socket failed (rc) while connecting or connected: said, counted,
 * and a reconnect scheduled. */
static void link_lost(bridge *b, int rc)
{
	const char *why = rc == MOSQ_ERR_ERRNO ? strerror(errno) : mosquitto_strerror(rc);

	if (b->connecting) {
		b->st.connect_failures++;
		fprintf(stderr, "cogw-mqtt: connecting to %s:%u failed: %s\n", b->cfg.host,
			b->cfg.port, why);
	} else {
		b->st.disconnects++;
		fprintf(stderr, "cogw-mqtt: lost the broker (%s); %zu message(s) queued\n", why,
			b->q_len);
	}
	mosquitto_disconnect(b->mosq);
	schedule_reconnect(b);
}

void link_service(bridge *b, uint32_t ev)
{
	uint64_t now = bridge_now_ms();
	int rc = MOSQ_ERR_SUCCESS;

	if (b->connected || b->connecting) {
		if (ev & (EPOLLIN | EPOLLERR | EPOLLHUP))
			rc = mosquitto_loop_read(b->mosq, 1);
		if (rc == MOSQ_ERR_SUCCESS && ((ev & EPOLLOUT) || mosquitto_want_write(b->mosq)))
			rc = mosquitto_loop_write(b->mosq, 1);
		if (rc == MOSQ_ERR_SUCCESS)
			rc = mosquitto_loop_misc(b->mosq);
		if (rc != MOSQ_ERR_SUCCESS && (b->connected || b->connecting)) {
			link_lost(b, rc);
		} else if (b->connecting && now >= b->next_connect_ms) {
			b->st.connect_failures++;
			fprintf(stderr, "cogw-mqtt: no CONNACK from %s:%u within %u s\n",
				b->cfg.host, b->cfg.port, b->cfg.keepalive_s);
			mosquitto_disconnect(b->mosq);
			schedule_reconnect(b);
		}
	}
	if (!b->connected && !b->connecting && !b->stopping && now >= b->next_connect_ms)
		try_connect(b);
	if (b->connected)
		flush_queue(b);
}

uint64_t link_next_deadline(const bridge *b)
{
	return b->connected ? bridge_now_ms() + 1000 : b->next_connect_ms;
}

void link_stop(bridge *b)
{
	char *bye;

	b->stopping = true;
	if (b->connected) {
		bye = status_payload("offline", "stopped", true);
		/* the will is for an unclean end; this one says it was intended */
		mosquitto_publish_v5(b->mosq, NULL, b->topic_status, (int)strlen(bye), bye, 1, true,
				     NULL);
		free(bye);
		b->connected = false; /* what follows is no loss of the broker */
		for (int i = 0; i < 20 && mosquitto_want_write(b->mosq); i++)
			if (mosquitto_loop_write(b->mosq, 1) != MOSQ_ERR_SUCCESS)
				break;
		mosquitto_disconnect(b->mosq);
		mosquitto_loop_write(b->mosq, 1);
	}
}

void link_free(bridge *b)
{
	while (b->q_head) {
		out_msg *m = b->q_head;

		b->q_head = m->next;
		msg_free(m);
	}
	b->q_tail = NULL;
	if (b->mosq)
		mosquitto_destroy(b->mosq);
	mosquitto_lib_cleanup();
}
