/* SPDX-License-Identifier: MIT */
/*
 * tests/fuzz/fuzz_mqtt_request.c - libFuzzer target for the request
 * decoder of cogw-mqtt (apps/cogw-mqtt/mqtt_request.c): what any client
 * the broker lets publish on a gateway's request topic can send.
 *
 * Properties:
 * - decoding never crashes or reads out of bounds (ASan/UBSan), whatever
 *   the bytes (NULs, invalid UTF-8, deep nesting, huge numbers);
 * - the result is OK or one of the decoder's errors, with a reason;
 * - an accepted request is consistent: network and node in range (node 0
 *   only for NMT), a type for every SDO and watch, a write's value of at
 *   most the buffer and exactly the type's size when it has one, an NMT
 *   command with a name, id and reply_to NUL-terminated, the reply topic
 *   without wildcards;
 * - the payload limit holds: above it, TOO_BIG and nothing else.
 *
 * Built by `make fuzz` (clang only). tests/unit/test_fuzz_mqtt_request_corpus.c
 * includes this file and replays tests/fuzz/corpus/mqtt_request/ with gcc.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "apps/cogw-mqtt/mqtt_request.h"

int fuzz_mqtt_request_one(const uint8_t *data, size_t size);

#define FUZZ_MAX_PAYLOAD 4096u

static int check_accepted(const mqtt_request *r)
{
	if (r->net < 1 || r->net > 127 || r->node > 127)
		return 10;
	if (r->op == MQTT_OP_NMT)
		return mqtt_nmt_command_name(r->nmt_cs) ? 0 : 11;
	if (r->node == 0 || !r->type)
		return 12;
	if (r->op == MQTT_OP_SDO_WRITE) {
		if (r->value_len > sizeof r->value)
			return 13;
		if (r->type->size && r->value_len != r->type->size)
			return 14;
	}
	return 0;
}

int fuzz_mqtt_request_one(const uint8_t *data, size_t size)
{
	static mqtt_request r;
	char err[512];
	int rc;

	err[0] = 0;
	rc = mqtt_request_decode(data, size, FUZZ_MAX_PAYLOAD, &r, err, sizeof err);
	if (size > FUZZ_MAX_PAYLOAD)
		return rc == MQTT_REQ_TOO_BIG ? 0 : 1;
	if (rc != MQTT_REQ_OK && rc != MQTT_REQ_MALFORMED && rc != MQTT_REQ_BAD_OP &&
	    rc != MQTT_REQ_BAD_FIELD)
		return 2;
	if (memchr(r.id, 0, sizeof r.id) == NULL ||
	    memchr(r.reply_to, 0, sizeof r.reply_to) == NULL)
		return 3;
	if (strpbrk(r.reply_to, "+#") || r.reply_to[0] == '$')
		return 4;
	if (rc != MQTT_REQ_OK)
		return err[0] ? 0 : 5; /* a refusal always says why */
	return check_accepted(&r);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	if (fuzz_mqtt_request_one(data, size) != 0)
		abort();
	return 0;
}
