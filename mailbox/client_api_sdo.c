/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_api_sdo.c - libcogw, the object dictionary services: the daemon's own
 * dictionary (OD read/write, store 1010h / restore 1011h) and SDO transfers to
 * a node of the line or, routed (CiA 302-7), of another network, with the typed
 * wrappers (numbers little-endian and float IEEE 754 single, CiA 301 7.1).
 * Each call is one request and its answer through client_call()
 * (mailbox/client_internal.h).
 */
#include "mailbox/client_internal.h"

#include <string.h>

int cogw_od_read(cogw *h, unsigned line, uint16_t index, uint8_t sub, void *buf, size_t cap,
		 size_t *len, unsigned timeout_ms, uint32_t *abort)
{
	mbx_obj_req r = { .index = index, .sub = sub };

	return client_call(h, line, MBX_CMD_OD_READ, &r, sizeof r, NULL, 0, buf, cap, len, abort,
			   timeout_ms);
}

int cogw_od_write(cogw *h, unsigned line, uint16_t index, uint8_t sub, const void *data, size_t len,
		  unsigned timeout_ms, uint32_t *abort)
{
	mbx_obj_req r = { .index = index, .sub = sub };

	return client_call(h, line, MBX_CMD_OD_WRITE, &r, sizeof r, data, len, NULL, 0, NULL, abort,
			   timeout_ms);
}

int cogw_sdo_read_ex(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub,
		     const cogw_sdo_opts *o, void *buf, size_t cap, size_t *len,
		     unsigned timeout_ms, uint32_t *abort)
{
	mbx_sdo_req r = { .node = node, .index = index, .sub = sub };

	if (o) {
		r.mode = o->mode;
		r.timeout_ms = o->sdo_timeout_ms;
	}
	return client_call(h, line, MBX_CMD_SDO_UPLOAD, &r, sizeof r, NULL, 0, buf, cap, len, abort,
			   timeout_ms);
}

int cogw_sdo_write_ex(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub,
		      const cogw_sdo_opts *o, const void *data, size_t len, unsigned timeout_ms,
		      uint32_t *abort)
{
	mbx_sdo_req r = { .node = node, .index = index, .sub = sub };

	if (o) {
		r.mode = o->mode;
		r.timeout_ms = o->sdo_timeout_ms;
	}
	return client_call(h, line, MBX_CMD_SDO_DOWNLOAD, &r, sizeof r, data, len, NULL, 0, NULL,
			   abort, timeout_ms);
}

static mbx_gw_sdo_req gw_sdo_req(uint16_t net, uint8_t node, uint16_t index, uint8_t sub,
				 const cogw_sdo_opts *o)
{
	mbx_gw_sdo_req r = { .net = net, .sdo = { .node = node, .index = index, .sub = sub } };

	if (o) {
		r.sdo.mode = o->mode;
		r.sdo.timeout_ms = o->sdo_timeout_ms;
	}
	return r;
}

int cogw_sdo_read_net(cogw *h, unsigned line, uint16_t net, uint8_t node, uint16_t index,
		      uint8_t sub, const cogw_sdo_opts *o, void *buf, size_t cap, size_t *len,
		      unsigned timeout_ms, uint32_t *abort)
{
	mbx_gw_sdo_req r = gw_sdo_req(net, node, index, sub, o);

	return client_call(h, line, MBX_CMD_GW_SDO_UPLOAD, &r, sizeof r, NULL, 0, buf, cap, len,
			   abort, timeout_ms);
}

int cogw_sdo_write_net(cogw *h, unsigned line, uint16_t net, uint8_t node, uint16_t index,
		       uint8_t sub, const cogw_sdo_opts *o, const void *data, size_t len,
		       unsigned timeout_ms, uint32_t *abort)
{
	mbx_gw_sdo_req r = gw_sdo_req(net, node, index, sub, o);

	return client_call(h, line, MBX_CMD_GW_SDO_DOWNLOAD, &r, sizeof r, data, len, NULL, 0, NULL,
			   abort, timeout_ms);
}

int cogw_sdo_read(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub, void *buf,
		  size_t cap, size_t *len, unsigned timeout_ms, uint32_t *abort)
{
	return cogw_sdo_read_ex(h, line, node, index, sub, NULL, buf, cap, len, timeout_ms, abort);
}

int cogw_sdo_write(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub,
		   const void *data, size_t len, unsigned timeout_ms, uint32_t *abort)
{
	return cogw_sdo_write_ex(h, line, node, index, sub, NULL, data, len, timeout_ms, abort);
}

/* Read exactly n bytes (a numeric value) into a little-endian integer. */
static int read_num(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub, size_t n,
		    uint64_t *v, unsigned timeout_ms, uint32_t *abort)
{
	uint8_t b[8];
	size_t len = 0;
	uint32_t ab = 0;
	int rc = cogw_sdo_read(h, line, node, index, sub, b, sizeof b, &len, timeout_ms, &ab);

	if (rc == 0 && len != n) {
		rc = COGW_E_ABORT;
		ab = 0x06070010u; /* data type does not match, length */
	} else if (rc == COGW_E_TRUNCATED) {
		rc = COGW_E_ABORT;
		ab = 0x06070012u; /* length too high */
	}
	if (abort)
		*abort = ab;
	if (rc)
		return rc;
	*v = 0;
	for (size_t i = 0; i < n; i++)
		*v |= (uint64_t)b[i] << (8 * i);
	return 0;
}

static int write_num(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub, size_t n,
		     uint64_t v, unsigned timeout_ms, uint32_t *abort)
{
	uint8_t b[8];

	for (size_t i = 0; i < n; i++)
		b[i] = (uint8_t)(v >> (8 * i));
	return cogw_sdo_write(h, line, node, index, sub, b, n, timeout_ms, abort);
}

#define TYPED(suffix, type, n)                                                                  \
	int cogw_sdo_read_##suffix(cogw *h, unsigned line, uint8_t node, uint16_t index,        \
				   uint8_t sub, type *v, unsigned timeout_ms, uint32_t *abort)  \
	{                                                                                       \
		uint64_t x;                                                                     \
		int rc = read_num(h, line, node, index, sub, n, &x, timeout_ms, abort);         \
		if (rc == 0)                                                                    \
			*v = (type)x;                                                           \
		return rc;                                                                      \
	}                                                                                       \
	int cogw_sdo_write_##suffix(cogw *h, unsigned line, uint8_t node, uint16_t index,       \
				    uint8_t sub, type v, unsigned timeout_ms, uint32_t *abort)  \
	{                                                                                       \
		return write_num(h, line, node, index, sub, n, (uint64_t)v, timeout_ms, abort); \
	}

TYPED(u8, uint8_t, 1)
TYPED(u16, uint16_t, 2)
TYPED(u32, uint32_t, 4)
TYPED(u64, uint64_t, 8)
#undef TYPED

int cogw_sdo_read_float(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub, float *v,
			unsigned timeout_ms, uint32_t *abort)
{
	uint64_t x;
	uint32_t bits;
	int rc = read_num(h, line, node, index, sub, 4, &x, timeout_ms, abort);

	if (rc == 0) {
		bits = (uint32_t)x;
		memcpy(v, &bits, sizeof *v); /* IEEE 754 single, as CiA 301 */
	}
	return rc;
}

int cogw_sdo_write_float(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub, float v,
			 unsigned timeout_ms, uint32_t *abort)
{
	uint32_t bits;

	memcpy(&bits, &v, sizeof bits);
	return write_num(h, line, node, index, sub, 4, bits, timeout_ms, abort);
}

int cogw_sdo_read_string(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub, char *s,
			 size_t cap, unsigned timeout_ms, uint32_t *abort)
{
	size_t len = 0;
	int rc;

	if (!s || cap == 0)
		return COGW_E_INVAL;
	rc = cogw_sdo_read(h, line, node, index, sub, s, cap - 1, &len, timeout_ms, abort);
	if (rc == 0 || rc == COGW_E_TRUNCATED)
		s[len < cap - 1 ? len : cap - 1] = 0;
	else
		s[0] = 0;
	return rc;
}

int cogw_sdo_write_string(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub,
			  const char *s, unsigned timeout_ms, uint32_t *abort)
{
	if (!s)
		return COGW_E_INVAL;
	return cogw_sdo_write(h, line, node, index, sub, s, strlen(s), timeout_ms, abort);
}

int cogw_store(cogw *h, unsigned line, uint8_t sub, unsigned timeout_ms)
{
	mbx_store_req r = { .sub = sub };

	return client_call(h, line, MBX_CMD_STORE, &r, sizeof r, NULL, 0, NULL, 0, NULL, NULL,
			   timeout_ms);
}

int cogw_restore(cogw *h, unsigned line, uint8_t sub, unsigned timeout_ms)
{
	mbx_store_req r = { .sub = sub };

	return client_call(h, line, MBX_CMD_RESTORE, &r, sizeof r, NULL, 0, NULL, 0, NULL, NULL,
			   timeout_ms);
}
