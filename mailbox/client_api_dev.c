/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_api_dev.c - libcogw, device objects of the line's slaves
 * (docs/devices.md): their layouts, watches, reads and writes. Each call
 * is one request and its answer through client_call()
 * (mailbox/client_internal.h); the answers' and values' formats are
 * client_api_values.c's.
 */
#include "mailbox/client_internal.h"

#include <stdlib.h>
#include <string.h>

/* ---- requests ------------------------------------------------------------------ */

int cogw_dev_layout(cogw *h, unsigned line, uint8_t node, void *buf, size_t cap, size_t *len,
		    unsigned timeout_ms)
{
	mbx_dev_node_req r = { .node = node };

	return client_call(h, line, MBX_CMD_DEV_LAYOUT, &r, sizeof r, NULL, 0, buf, cap, len, NULL,
			   timeout_ms);
}

int cogw_dev_forwards(cogw *h, unsigned line, mbx_dev_forward *out, size_t cap, size_t *n,
		      unsigned timeout_ms)
{
	size_t len = 0;
	int rc = client_call(h, line, MBX_CMD_DEV_FORWARDS, NULL, 0, NULL, 0, out,
			     cap * sizeof *out, &len, NULL, timeout_ms);
	if (rc < 0 && rc != COGW_E_TRUNCATED)
		return rc;
	if (len % sizeof *out)
		return COGW_E_PROTOCOL;
	*n = len / sizeof *out;
	return rc;
}

int cogw_dev_watch(cogw *h, unsigned line, const mbx_dev_obj_req *obj, uint32_t min_interval_ms,
		   mbx_dev_watch_resp *resp, unsigned timeout_ms, uint32_t *abort)
{
	mbx_dev_watch_req r = { .obj = *obj, .min_interval_ms = min_interval_ms };
	mbx_dev_watch_resp a;
	size_t len = 0;
	int rc = client_call(h, line, MBX_CMD_DEV_WATCH, &r, sizeof r, NULL, 0, &a, sizeof a, &len,
			     abort, timeout_ms);

	if (rc == 0 && len != sizeof a)
		rc = COGW_E_PROTOCOL;
	if (rc == 0 && resp)
		*resp = a;
	return rc;
}

int cogw_dev_unwatch(cogw *h, unsigned line, const mbx_dev_obj_req *obj, unsigned timeout_ms)
{
	return client_call(h, line, MBX_CMD_DEV_UNWATCH, obj, sizeof *obj, NULL, 0, NULL, 0, NULL,
			   NULL, timeout_ms);
}

int cogw_dev_read(cogw *h, unsigned line, const mbx_dev_obj_req *obj, uint32_t max_age_ms,
		  mbx_dev_value *v, void *buf, size_t cap, size_t *len, unsigned timeout_ms,
		  uint32_t *abort)
{
	mbx_dev_read_req r = { .obj = *obj, .max_age_ms = max_age_ms };
	size_t acap = sizeof *v + cap, alen = 0;
	uint8_t *a = malloc(acap);
	const uint8_t *data;
	int rc;

	if (!a)
		return COGW_E_NOMEM;
	rc = client_call(h, line, MBX_CMD_DEV_READ, &r, sizeof r, NULL, 0, a, acap, &alen, abort,
			 timeout_ms);
	if (rc == 0 || rc == COGW_E_TRUNCATED) {
		if (alen < sizeof *v) {
			rc = COGW_E_PROTOCOL;
		} else {
			memcpy(v, a, sizeof *v);
			*len = v->len;
			if (rc == 0 && cogw_dev_value_parse(a, alen, v, &data) < 0)
				rc = COGW_E_PROTOCOL;
			else if (rc == 0)
				memcpy(buf, data, v->len);
		}
	}
	free(a);
	return rc;
}

int cogw_dev_write(cogw *h, unsigned line, const mbx_dev_obj_req *obj, const void *data, size_t len,
		   mbx_dev_write_resp *resp, unsigned timeout_ms, uint32_t *abort)
{
	mbx_dev_write_resp a;
	size_t alen = 0;
	int rc = client_call(h, line, MBX_CMD_DEV_WRITE, obj, sizeof *obj, data, len, &a, sizeof a,
			     &alen, abort, timeout_ms);

	if (rc == 0 && alen != sizeof a)
		rc = COGW_E_PROTOCOL;
	if (rc == 0 && resp)
		*resp = a;
	return rc;
}
