/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_api_scan.c - libcogw, the node scan and its cache: one
 * request and its answer each, through client_call()
 * (mailbox/client_internal.h).
 */
#include <string.h>

#include "mailbox/client_internal.h"
#include "mailbox/cogw_scan.h"

/* The answer's layout: figures, then `found` entries that fill it. */
static int take(const uint8_t *buf, size_t len, cogw_scan_result *out)
{
	if (len < sizeof out->figures)
		return COGW_E_PROTOCOL;
	memcpy(&out->figures, buf, sizeof out->figures);
	size_t n = (len - sizeof out->figures) / sizeof out->nodes[0];
	if (n != out->figures.found || n > 127 ||
	    len != sizeof out->figures + n * sizeof out->nodes[0])
		return COGW_E_PROTOCOL;
	memcpy(out->nodes, buf + sizeof out->figures, n * sizeof out->nodes[0]);
	out->n_nodes = (unsigned)n;
	return 0;
}

static int call(cogw *h, unsigned line, uint16_t code, const mbx_scan_req *req,
		cogw_scan_result *out, unsigned timeout_ms)
{
	uint8_t buf[sizeof(mbx_scan_resp) + 127 * sizeof(mbx_node_ident)];
	size_t len = 0;
	memset(out, 0, sizeof *out);
	int rc = client_call(h, line, code, req, req ? sizeof *req : 0, NULL, 0, buf, sizeof buf,
			     &len, NULL, timeout_ms);
	return rc < 0 ? rc : take(buf, len, out);
}

unsigned cogw_scan_bound_ms(unsigned n, unsigned parallel, unsigned timeout_ms)
{
	if (!parallel)
		parallel = 1;
	return (n + parallel - 1) / parallel * 5u * timeout_ms;
}

int cogw_node_scan(cogw *h, unsigned line, uint8_t first, uint8_t last, unsigned timeout_ms,
		   unsigned parallel, unsigned wait_ms, cogw_scan_result *out)
{
	mbx_scan_req r = { .first = first, .last = last };
	if (!out || first < 1 || last > 127 || first > last ||
	    timeout_ms > MBX_SCAN_TIMEOUT_MAX_MS || parallel > 128)
		return COGW_E_INVAL;
	r.timeout_ms = (uint16_t)timeout_ms;
	r.parallel = (uint8_t)parallel;
	/* the daemon answers when the scan ended: by default wait for its
	 * bound with the worst of the line's defaults (one channel, 100 ms
	 * per frame) and 5 s more */
	if (!wait_ms)
		wait_ms = cogw_scan_bound_ms(last - first + 1u, parallel ? parallel : 1,
					     timeout_ms ? timeout_ms : 100u) +
			  5000u;
	return call(h, line, MBX_CMD_NODE_SCAN, &r, out, wait_ms);
}

int cogw_node_scan_cache(cogw *h, unsigned line, cogw_scan_result *out)
{
	if (!out)
		return COGW_E_INVAL;
	return call(h, line, MBX_CMD_NODE_SCAN_CACHE, NULL, out, 0);
}
