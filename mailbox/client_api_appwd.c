/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_api_appwd.c - libcogw, the application on the mailbox: the
 * application watchdog, the hold on the daemon's own OPERATIONAL and host
 * ready / not ready (docs/application.md). Each call is one request and
 * its answer through client_call() (mailbox/client_internal.h).
 */
#include "mailbox/client_internal.h"

#include <string.h>

int cogw_app_watchdog(cogw *h, unsigned line, uint32_t interval_ms, uint32_t reactions,
		      mbx_appwd_resp *out, unsigned timeout_ms)
{
	mbx_appwd_req r = { .interval_ms = interval_ms, .reactions = reactions };
	mbx_appwd_resp resp = { 0 };
	size_t len = 0;
	int rc = client_call(h, line, MBX_CMD_APP_WATCHDOG, &r, sizeof r, NULL, 0, &resp,
			     sizeof resp, &len, NULL, timeout_ms);

	if (!rc && interval_ms && len != sizeof resp)
		rc = COGW_E_PROTOCOL;
	if (out)
		*out = resp;
	return rc;
}

int cogw_app_keepalive(cogw *h, unsigned line, unsigned timeout_ms)
{
	return client_call(h, line, MBX_CMD_APP_KEEPALIVE, NULL, 0, NULL, 0, NULL, 0, NULL, NULL,
			   timeout_ms);
}

int cogw_app_hold(cogw *h, unsigned line, int hold, mbx_appwd_nmt *out, unsigned timeout_ms)
{
	mbx_appwd_hold_req r = { .hold = hold ? 1 : 0 };
	mbx_appwd_nmt resp = { 0 };
	size_t len = 0;
	int rc = client_call(h, line, MBX_CMD_APP_HOLD, &r, sizeof r, NULL, 0, &resp, sizeof resp,
			     &len, NULL, timeout_ms);

	if (!rc && len != sizeof resp)
		rc = COGW_E_PROTOCOL;
	if (out)
		*out = resp;
	return rc;
}

int cogw_host_ready(cogw *h, unsigned line, int ready, unsigned timeout_ms)
{
	mbx_host_ready_req r = { .ready = ready ? 1 : 0 };

	return client_call(h, line, MBX_CMD_HOST_READY, &r, sizeof r, NULL, 0, NULL, 0, NULL, NULL,
			   timeout_ms);
}

int cogw_app_status(cogw *h, unsigned line, mbx_appwd_status *st, mbx_appwd_entry *wd, size_t cap,
		    unsigned timeout_ms)
{
	uint8_t buf[sizeof(mbx_appwd_status) + MBX_APPWD_MAX * sizeof(mbx_appwd_entry)];
	mbx_appwd_status s;
	size_t len = 0;
	int rc = client_call(h, line, MBX_CMD_APP_STATUS, NULL, 0, NULL, 0, buf, sizeof buf, &len,
			     NULL, timeout_ms);

	if (rc)
		return rc;
	if (len < sizeof s)
		return COGW_E_PROTOCOL;
	memcpy(&s, buf, sizeof s);
	if (s.n > MBX_APPWD_MAX || len != sizeof s + s.n * sizeof(mbx_appwd_entry))
		return COGW_E_PROTOCOL;
	if (st)
		*st = s;
	if (wd)
		memcpy(wd, buf + sizeof s, (s.n < cap ? s.n : cap) * sizeof *wd);
	return s.n;
}
