/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_api_health.c - libcogw, the line's bus health: its
 * counters and their reset. One request and its answer each, through
 * client_call() (mailbox/client_internal.h).
 */
#include "mailbox/client_internal.h"
#include "mailbox/cogw_health.h"

int cogw_line_health(cogw *h, unsigned line, mbx_line_health *out, unsigned timeout_ms)
{
	size_t len = 0;
	int rc = client_call(h, line, MBX_CMD_LINE_HEALTH, NULL, 0, NULL, 0, out, sizeof *out, &len,
			     NULL, timeout_ms);

	return rc == 0 && len != sizeof *out ? COGW_E_PROTOCOL : rc;
}

int cogw_line_health_reset(cogw *h, unsigned line, unsigned timeout_ms)
{
	return client_call(h, line, MBX_CMD_LINE_HEALTH_RESET, NULL, 0, NULL, 0, NULL, 0, NULL,
			   NULL, timeout_ms);
}
