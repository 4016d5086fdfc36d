/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-mqtt/mqtt_request.h - the requests the bridge takes from the
 * broker (docs/mqtt.md "Requests"): a JSON payload into one checked
 * mqtt_request, and the role each kind needs. No I/O, no global state;
 * what any publisher allowed on the request topic can send, so every field
 * is validated here (and fuzzed: tests/fuzz/fuzz_mqtt_request.c).
 */
#ifndef COGW_MQTT_REQUEST_H
#define COGW_MQTT_REQUEST_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "apps/cogw-ascii/ascii_value.h"

#define MQTT_REQ_ID_MAX 65      /* "id": 64 bytes */
#define MQTT_REQ_TOPIC_MAX 256  /* "reply_to" */
#define MQTT_REQ_VALUE_MAX 4096 /* bytes an SDO write may carry */

typedef enum mqtt_op {
	MQTT_OP_SDO_READ,
	MQTT_OP_SDO_WRITE,
	MQTT_OP_NMT,
	MQTT_OP_WATCH_ADD,
	MQTT_OP_WATCH_REMOVE,
} mqtt_op;

/* Why a request was not taken (the "error" member of the reply). */
typedef enum mqtt_req_err {
	MQTT_REQ_OK = 0,
	MQTT_REQ_TOO_BIG = -1,   /* payload above requests.max_payload */
	MQTT_REQ_MALFORMED = -2, /* not a JSON object */
	MQTT_REQ_BAD_OP = -3,    /* "op" missing or not known */
	MQTT_REQ_BAD_FIELD = -4, /* a member missing, of a wrong type or out of range */
} mqtt_req_err;

typedef struct mqtt_request {
	mqtt_op op;
	uint16_t net; /* 1..127 */
	uint8_t node; /* 1..127 (NMT: 0 = all) */
	uint16_t index;
	uint8_t sub;
	const ascii_type *type;   /* SDO, watch: how the value is read and written */
	uint8_t nmt_cs;           /* CiA 301 §7.2.8.3.1 command specifier */
	uint32_t sdo_timeout_ms;  /* per SDO frame on the bus, 0 = line default */
	uint32_t min_interval_ms; /* watch_add */
	bool has_id;
	char id[MQTT_REQ_ID_MAX];          /* echoed in the reply (MQTT 3.1.1 correlation) */
	char reply_to[MQTT_REQ_TOPIC_MAX]; /* MQTT 3.1.1 response topic, "" = none */
	size_t value_len;
	uint8_t value[MQTT_REQ_VALUE_MAX]; /* sdo_write: wire bytes */
} mqtt_request;

/* Decode payload[0..len) (not NUL-terminated). On failure err holds the
 * reason ("index: ..."), and r->id / r->reply_to whatever could be read
 * of them, so that the refusal still reaches its requester. */
int mqtt_request_decode(const void *payload, size_t len, size_t max_payload, mqtt_request *r,
			char *err, size_t errlen);
const char *mqtt_req_err_to_string(int e); /* "too_big", "malformed", ... */
const char *mqtt_op_to_string(mqtt_op op);
/* The mqtt_role an operation needs. */
uint8_t mqtt_op_role(mqtt_op op);
/* "start", "stop", ... of a command specifier, NULL if not one. */
const char *mqtt_nmt_command_name(uint8_t cs);

#endif /* COGW_MQTT_REQUEST_H */
