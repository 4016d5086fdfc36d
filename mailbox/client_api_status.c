/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_api_status.c - libcogw, the line's status, the mailbox counters and ping.
 * Each call is one request and its answer through client_call()
 * (mailbox/client_internal.h).
 */
#include "mailbox/client_internal.h"

#include <stddef.h>
#include <string.h>

int cogw_line_status(cogw *h, unsigned line, mbx_line_status *st, unsigned timeout_ms)
{
	size_t len = 0;
	int rc = client_call(h, line, MBX_CMD_LINE_STATUS, NULL, 0, NULL, 0, st, sizeof *st, &len,
			     NULL, timeout_ms);

	return rc == 0 && len != sizeof *st ? COGW_E_PROTOCOL : rc;
}

int cogw_mbx_stats(cogw *h, unsigned line, mbx_stats_wire *st, unsigned timeout_ms)
{
	size_t len = 0;
	int rc;

	memset(st, 0, sizeof *st);
	rc = client_call(h, line, MBX_CMD_MBX_STATS, NULL, 0, NULL, 0, st, sizeof *st, &len, NULL,
			 timeout_ms);
	/* An older daemon's answer ends before the counters added later
	 * (left 0). */
	return rc == 0 && len != sizeof *st && len != offsetof(mbx_stats_wire, reg_refused) &&
			       len != offsetof(mbx_stats_wire, late_wakes) &&
			       len != offsetof(mbx_stats_wire, xfer_failed)
		       ? COGW_E_PROTOCOL
		       : rc;
}

int cogw_ping(cogw *h, unsigned line, unsigned timeout_ms)
{
	mbx_ping_resp r;

	return client_call(h, line, MBX_CMD_PING, NULL, 0, NULL, 0, &r, sizeof r, NULL, NULL,
			   timeout_ms);
}
