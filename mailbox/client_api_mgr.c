/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_api_mgr.c - libcogw, the CiA 302 manager (status, node diagnostics, boot,
 * start, NMT requests, counters, nodes at run time) and the gateway (routes, routed sessions).
 * Each call is one request and its answer through client_call()
 * (mailbox/client_internal.h).
 */
#include "mailbox/client_internal.h"

#include <string.h>

int cogw_mgr_status(cogw *h, unsigned line, mbx_mgr_status *st, unsigned timeout_ms)
{
	size_t len = 0;
	int rc = client_call(h, line, MBX_CMD_MGR_STATUS, NULL, 0, NULL, 0, st, sizeof *st, &len,
			     NULL, timeout_ms);

	if (!rc && len != sizeof *st)
		return COGW_E_PROTOCOL;
	return rc;
}

int cogw_mgr_node_diag(cogw *h, unsigned line, uint8_t node, mbx_mgr_node_diag *d,
		       unsigned timeout_ms)
{
	mbx_mgr_node_req r = { .node = node };
	size_t len = 0;
	int rc = client_call(h, line, MBX_CMD_MGR_NODE_DIAG, &r, sizeof r, NULL, 0, d, sizeof *d,
			     &len, NULL, timeout_ms);

	if (!rc && len != sizeof *d)
		return COGW_E_PROTOCOL;
	return rc;
}

int cogw_mgr_boot(cogw *h, unsigned line, uint8_t node, unsigned timeout_ms)
{
	mbx_mgr_node_req r = { .node = node };
	return client_call(h, line, MBX_CMD_MGR_BOOT, &r, sizeof r, NULL, 0, NULL, 0, NULL, NULL,
			   timeout_ms);
}

int cogw_mgr_start(cogw *h, unsigned line, unsigned timeout_ms)
{
	return client_call(h, line, MBX_CMD_MGR_START, NULL, 0, NULL, 0, NULL, 0, NULL, NULL,
			   timeout_ms);
}

int cogw_mgr_request_nmt(cogw *h, unsigned line, uint8_t node, uint8_t cmd, unsigned timeout_ms)
{
	mbx_mgr_nmt_req r = { .node = node, .cmd = cmd };
	return client_call(h, line, MBX_CMD_MGR_REQUEST_NMT, &r, sizeof r, NULL, 0, NULL, 0, NULL,
			   NULL, timeout_ms);
}

int cogw_mgr_reset_counters(cogw *h, unsigned line, unsigned timeout_ms)
{
	return client_call(h, line, MBX_CMD_MGR_RESET_COUNTERS, NULL, 0, NULL, 0, NULL, 0, NULL,
			   NULL, timeout_ms);
}

int cogw_mgr_node_set(cogw *h, unsigned line, const mbx_mgr_node_set_req *req, const uint8_t *cdcf,
		      size_t cdcf_len, unsigned timeout_ms)
{
	return client_call(h, line, MBX_CMD_MGR_NODE_SET, req, sizeof *req, cdcf, cdcf_len, NULL, 0,
			   NULL, NULL, timeout_ms);
}

int cogw_mgr_node_remove(cogw *h, unsigned line, uint8_t node, unsigned timeout_ms)
{
	mbx_mgr_node_set_req r = { .node = node, .op = MBX_NODE_REMOVE };
	return cogw_mgr_node_set(h, line, &r, NULL, 0, timeout_ms);
}

int cogw_gw_status(cogw *h, unsigned line, mbx_gw_status *st, mbx_gw_route *routes, size_t cap,
		   size_t *n, mbx_gw_session *sessions, size_t s_cap, size_t *n_s,
		   unsigned timeout_ms)
{
	static __thread uint8_t buf[sizeof(mbx_gw_status) + 255 * sizeof(mbx_gw_route) +
				    255 * sizeof(mbx_gw_session)];
	size_t len = 0, off = sizeof *st;
	int rc = client_call(h, line, MBX_CMD_GW_ROUTES, NULL, 0, NULL, 0, buf, sizeof buf, &len,
			     NULL, timeout_ms);

	if (rc)
		return rc;
	if (len < sizeof *st)
		return COGW_E_PROTOCOL;
	memcpy(st, buf, sizeof *st);
	if (len !=
	    sizeof *st + st->routes * sizeof(mbx_gw_route) + st->active * sizeof(mbx_gw_session))
		return COGW_E_PROTOCOL;
	if (n)
		*n = st->routes;
	for (size_t i = 0; routes && i < st->routes && i < cap; i++)
		memcpy(&routes[i], buf + off + i * sizeof(mbx_gw_route), sizeof routes[i]);
	off += st->routes * sizeof(mbx_gw_route);
	if (n_s)
		*n_s = st->active;
	for (size_t i = 0; sessions && i < st->active && i < s_cap; i++) {
		memcpy(&sessions[i], buf + off + i * sizeof(mbx_gw_session), sizeof sessions[i]);
		sessions[i].state[sizeof sessions[i].state - 1] = '\0';
	}
	return 0;
}

int cogw_gw_routes(cogw *h, unsigned line, mbx_gw_status *st, mbx_gw_route *routes, size_t cap,
		   size_t *n, unsigned timeout_ms)
{
	return cogw_gw_status(h, line, st, routes, cap, n, NULL, 0, NULL, timeout_ms);
}
