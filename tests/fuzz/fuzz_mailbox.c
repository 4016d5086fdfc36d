/* SPDX-License-Identifier: MIT */
/*
 * tests/fuzz/fuzz_mailbox.c - libFuzzer target for the mailbox wire
 * format (mailbox/proto.c): what any local process can put into a line's
 * command queue, and what a client reads from its queues.
 *
 * Properties checked on every input:
 * - decoding and validating never crash or read out of bounds (ASan/UBSan);
 * - a refused header or command names a reason, and the status it gives is
 *   that reason's status (mbx_bad_status);
 * - a header that decodes re-encodes to the very same bytes, and a valid
 *   message rebuilt with mbx_msg_build is byte-identical (no field is
 *   silently dropped or normalised);
 * - event payload validation answers 0 or a negative status.
 *
 * Built by `make fuzz` (clang only). tests/unit/test_fuzz_corpora.c
 * includes this file and replays tests/fuzz/corpus/mailbox/ with gcc, so
 * the same checks run in `make unit`.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "mailbox/proto.h"

int fuzz_mailbox_one(const uint8_t *data, size_t size);

int fuzz_mailbox_one(const uint8_t *data, size_t size)
{
	static uint8_t again[MBX_MSG_MAX];
	mbx_hdr h;
	mbx_bad bad = MBX_BAD_NONE;
	int rc = mbx_hdr_decode(data, size, &h, &bad);

	if (rc) {
		if (rc >= 0 || bad == MBX_BAD_NONE || rc != mbx_bad_status(bad))
			return 1;
		return 0;
	}
	if (bad != MBX_BAD_NONE || (size_t)h.len + MBX_HDR_SIZE != size)
		return 2;
	mbx_hdr_encode(&h, again);
	if (memcmp(again, data, MBX_HDR_SIZE) != 0)
		return 3;
	const uint8_t *p = data + MBX_HDR_SIZE;

	if (h.kind == MBX_KIND_COMMAND) {
		rc = mbx_cmd_validate(&h, p, &bad);
		if (rc && (rc >= 0 || bad == MBX_BAD_NONE || rc != mbx_bad_status(bad)))
			return 4;
		if (!rc && bad != MBX_BAD_NONE)
			return 5;
	} else if (h.kind == MBX_KIND_EVENT) {
		rc = mbx_event_validate(h.code, p, h.len);
		if (rc > 0)
			return 6;
	}
	if (size > sizeof again)
		return 0;
	int n = mbx_msg_build(again, sizeof again, &h, p, h.len);

	if (n != (int)size || memcmp(again, data, size) != 0)
		return 7;
	return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	if (fuzz_mailbox_one(data, size))
		abort();
	return 0;
}
