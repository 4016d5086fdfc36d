/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_api_nmt.c - libcogw, network management: NMT commands, the node table,
 * and the LSS master services (CiA 305).
 * Each call is one request and its answer through client_call()
 * (mailbox/client_internal.h).
 */
#include "mailbox/client_internal.h"

#include <string.h>

int cogw_nmt(cogw *h, unsigned line, uint8_t cs, uint8_t node, unsigned timeout_ms)
{
	mbx_nmt_req r = { .cs = cs, .node = node };

	return client_call(h, line, MBX_CMD_NMT, &r, sizeof r, NULL, 0, NULL, 0, NULL, NULL,
			   timeout_ms);
}

int cogw_node_table(cogw *h, unsigned line, mbx_node_entry *tab, size_t cap, unsigned timeout_ms)
{
	mbx_node_entry all[128];
	size_t len = 0;
	int rc = client_call(h, line, MBX_CMD_NODE_TABLE, NULL, 0, NULL, 0, all, sizeof all, &len,
			     NULL, timeout_ms);

	if (rc)
		return rc;
	if (len % sizeof(mbx_node_entry))
		return COGW_E_PROTOCOL;
	size_t n = len / sizeof(mbx_node_entry);

	memcpy(tab, all, (n < cap ? n : cap) * sizeof *tab);
	return (int)n;
}

int cogw_lss(cogw *h, unsigned line, uint16_t cmd, const mbx_lss_req *req, mbx_lss_resp *resp,
	     unsigned timeout_ms)
{
	mbx_lss_resp tmp;
	size_t len = 0;
	int rc;

	if (!req || (cmd & 0xFF00u) != 0x0700u)
		return COGW_E_INVAL;
	memset(&tmp, 0, sizeof tmp);
	rc = client_call(h, line, cmd, req, sizeof *req, NULL, 0, &tmp, sizeof tmp, &len, NULL,
			 timeout_ms);
	if (resp)
		*resp = tmp;
	return rc;
}

int cogw_lss_switch_global(cogw *h, unsigned line, uint8_t mode, unsigned timeout_ms)
{
	mbx_lss_req r = { .mode = mode };

	return cogw_lss(h, line, MBX_CMD_LSS_SWITCH_GLOBAL, &r, NULL, timeout_ms);
}

int cogw_lss_switch_selective(cogw *h, unsigned line, uint32_t vendor, uint32_t product,
			      uint32_t revision, uint32_t serial, unsigned timeout_ms)
{
	mbx_lss_req r = { .vendor = vendor,
			  .product = product,
			  .rev_lo = revision,
			  .rev_hi = revision,
			  .ser_lo = serial,
			  .ser_hi = serial };

	return cogw_lss(h, line, MBX_CMD_LSS_SWITCH_SELECTIVE, &r, NULL, timeout_ms);
}

int cogw_lss_set_node_id(cogw *h, unsigned line, uint8_t node, unsigned timeout_ms)
{
	mbx_lss_req r = { .node = node };

	return cogw_lss(h, line, MBX_CMD_LSS_SET_NODE_ID, &r, NULL, timeout_ms);
}

int cogw_lss_set_bit_timing(cogw *h, unsigned line, uint8_t table, uint8_t index,
			    unsigned timeout_ms)
{
	mbx_lss_req r = { .table = table, .bit_index = index };

	return cogw_lss(h, line, MBX_CMD_LSS_SET_BIT_TIMING, &r, NULL, timeout_ms);
}

int cogw_lss_activate_bit_timing(cogw *h, unsigned line, uint16_t delay_ms, unsigned timeout_ms)
{
	mbx_lss_req r = { .delay_ms = delay_ms };

	return cogw_lss(h, line, MBX_CMD_LSS_ACTIVATE_BIT_TIMING, &r, NULL, timeout_ms);
}

int cogw_lss_store(cogw *h, unsigned line, unsigned timeout_ms)
{
	mbx_lss_req r = { 0 };

	return cogw_lss(h, line, MBX_CMD_LSS_STORE, &r, NULL, timeout_ms);
}

int cogw_lss_inquire(cogw *h, unsigned line, uint8_t what, uint32_t *value, unsigned timeout_ms)
{
	mbx_lss_req r = { .what = what };
	mbx_lss_resp s;
	int rc = cogw_lss(h, line, MBX_CMD_LSS_INQUIRE, &r, &s, timeout_ms);

	if (rc == 0 && value)
		*value = s.value;
	return rc;
}

int cogw_lss_identify_nonconf(cogw *h, unsigned line, unsigned timeout_ms)
{
	mbx_lss_req r = { 0 };
	mbx_lss_resp s;
	int rc = cogw_lss(h, line, MBX_CMD_LSS_IDENTIFY_NONCONF, &r, &s, timeout_ms);

	if (rc == COGW_E_NOT_FOUND)
		return 0;
	return rc ? rc : s.found != 0;
}

int cogw_lss_fastscan(cogw *h, unsigned line, uint32_t id[4], unsigned timeout_ms)
{
	mbx_lss_req r = { 0 };
	mbx_lss_resp s;
	int rc = cogw_lss(h, line, MBX_CMD_LSS_FASTSCAN, &r, &s, timeout_ms);

	if (rc == 0 && id)
		memcpy(id, s.id, sizeof s.id);
	return rc;
}
