/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_api_pdo.c - libcogw, process data and frames: RPDO status, TPDO request,
 * the daemon's own PDO-mapped objects, EMCY and raw CAN frames.
 * Each call is one request and its answer through client_call()
 * (mailbox/client_internal.h).
 */
#include "mailbox/client_internal.h"

#include <stdlib.h>
#include <string.h>

int cogw_rpdo_status(cogw *h, unsigned line, mbx_rpdo_status *st, mbx_rpdo_fault_entry *tab,
		     size_t cap, unsigned timeout_ms)
{
	struct {
		mbx_rpdo_status head;
		mbx_rpdo_fault_entry rows[512];
	} *a = malloc(sizeof *a);
	size_t len = 0;
	int rc;

	if (!a)
		return COGW_E_NOMEM;
	rc = client_call(h, line, MBX_CMD_RPDO_STATUS, NULL, 0, NULL, 0, a, sizeof *a, &len, NULL,
			 timeout_ms);
	if (rc == 0 && (len < sizeof a->head || a->head.n > 512 ||
			len != sizeof a->head + a->head.n * sizeof a->rows[0]))
		rc = COGW_E_PROTOCOL;
	if (rc == 0) {
		*st = a->head;
		memcpy(tab, a->rows, (a->head.n < cap ? a->head.n : cap) * sizeof *tab);
		rc = a->head.n;
	}
	free(a);
	return rc;
}

int cogw_pdo_request(cogw *h, unsigned line, uint16_t tpdo, unsigned timeout_ms)
{
	mbx_pdo_num_req r = { .pdo = tpdo };

	return client_call(h, line, MBX_CMD_PDO_REQUEST, &r, sizeof r, NULL, 0, NULL, 0, NULL, NULL,
			   timeout_ms);
}

int cogw_pdo_read(cogw *h, unsigned line, uint16_t index, uint8_t sub, void *buf, size_t cap,
		  size_t *len, unsigned timeout_ms)
{
	mbx_obj_req r = { .index = index, .sub = sub };

	return client_call(h, line, MBX_CMD_PDO_READ, &r, sizeof r, NULL, 0, buf, cap, len, NULL,
			   timeout_ms);
}

int cogw_pdo_write(cogw *h, unsigned line, uint16_t index, uint8_t sub, const void *data,
		   size_t len, int trigger, unsigned timeout_ms)
{
	mbx_obj_req r = { .index = index, .sub = sub, .flags = trigger ? MBX_PDO_TRIGGER : 0 };

	if (len == 0 || len > 8)
		return COGW_E_INVAL;
	return client_call(h, line, MBX_CMD_PDO_WRITE, &r, sizeof r, data, len, NULL, 0, NULL, NULL,
			   timeout_ms);
}

int cogw_emcy_send(cogw *h, unsigned line, uint16_t code, uint8_t reg, const uint8_t msef[5],
		   unsigned timeout_ms)
{
	mbx_emcy_req r = { .code = code, .reg = reg };

	if (msef)
		memcpy(r.msef, msef, sizeof r.msef);
	return client_call(h, line, MBX_CMD_EMCY_SEND, &r, sizeof r, NULL, 0, NULL, 0, NULL, NULL,
			   timeout_ms);
}

int cogw_raw_send(cogw *h, unsigned line, const mbx_raw_frame *frames, size_t n,
		  unsigned timeout_ms)
{
	if (!frames || n == 0 || n > MBX_RAW_SEND_MAX)
		return COGW_E_INVAL;
	return client_call(h, line, MBX_CMD_RAW_SEND, frames, n * sizeof *frames, NULL, 0, NULL, 0,
			   NULL, NULL, timeout_ms);
}
