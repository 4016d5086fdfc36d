/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_api_dev.c - libcogw, device objects of the line's slaves
 * (docs/devices.md): their layouts, watches, reads and writes, and the
 * typed value texts every client shares (cogwctl, the ASCII gateway, the
 * MQTT bridge). Each call is one request and its answer through
 * client_call() (mailbox/client_internal.h).
 */
#include "mailbox/client_internal.h"

#include <ctype.h>
#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

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

int cogw_dev_layout_check(const void *buf, size_t len)
{
	const uint8_t *p = buf;
	size_t off = 0;
	int nodes = 0;

	while (off < len) {
		mbx_dev_layout_node n;
		if (len - off < sizeof n)
			return COGW_E_PROTOCOL;
		memcpy(&n, p + off, sizeof n);
		off += sizeof n;
		for (unsigned k = 0; k < (unsigned)n.n_tpdo + n.n_rpdo; k++) {
			mbx_dev_layout_pdo d;
			if (len - off < sizeof d)
				return COGW_E_PROTOCOL;
			memcpy(&d, p + off, sizeof d);
			off += sizeof d;
			if (len - off < (size_t)d.n * sizeof(mbx_dev_layout_entry))
				return COGW_E_PROTOCOL;
			off += (size_t)d.n * sizeof(mbx_dev_layout_entry);
		}
		nodes++;
	}
	return nodes;
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

int cogw_dev_value_parse(const void *payload, size_t len, mbx_dev_value *v, const uint8_t **data)
{
	if (len < sizeof *v)
		return COGW_E_PROTOCOL;
	memcpy(v, payload, sizeof *v);
	if (v->len != len - sizeof *v)
		return COGW_E_PROTOCOL;
	*data = (const uint8_t *)payload + sizeof *v;
	return 0;
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

/* ---- typed values ----------------------------------------------------------------- */

static const cogw_type types[] = {
	{ "bool", "BOOLEAN", MBX_T_BOOLEAN, 1 },
	{ "u8", "UNSIGNED8", MBX_T_UNSIGNED8, 1 },
	{ "u16", "UNSIGNED16", MBX_T_UNSIGNED16, 2 },
	{ "u24", "UNSIGNED24", MBX_T_UNSIGNED24, 3 },
	{ "u32", "UNSIGNED32", MBX_T_UNSIGNED32, 4 },
	{ "u40", "UNSIGNED40", MBX_T_UNSIGNED40, 5 },
	{ "u48", "UNSIGNED48", MBX_T_UNSIGNED48, 6 },
	{ "u56", "UNSIGNED56", MBX_T_UNSIGNED56, 7 },
	{ "u64", "UNSIGNED64", MBX_T_UNSIGNED64, 8 },
	{ "i8", "INTEGER8", MBX_T_INTEGER8, 1 },
	{ "i16", "INTEGER16", MBX_T_INTEGER16, 2 },
	{ "i24", "INTEGER24", MBX_T_INTEGER24, 3 },
	{ "i32", "INTEGER32", MBX_T_INTEGER32, 4 },
	{ "i40", "INTEGER40", MBX_T_INTEGER40, 5 },
	{ "i48", "INTEGER48", MBX_T_INTEGER48, 6 },
	{ "i56", "INTEGER56", MBX_T_INTEGER56, 7 },
	{ "i64", "INTEGER64", MBX_T_INTEGER64, 8 },
	{ "r32", "REAL32", MBX_T_REAL32, 4 },
	{ "r64", "REAL64", MBX_T_REAL64, 8 },
	{ "time", "TIME_OF_DAY", MBX_T_TIME_OF_DAY, 6 },
	{ "timediff", "TIME_DIFFERENCE", MBX_T_TIME_DIFFERENCE, 6 },
	{ "string", "VISIBLE_STRING", MBX_T_VISIBLE_STRING, 0 },
	{ "hex", "OCTET_STRING", MBX_T_OCTET_STRING, 0 },
	{ "unicode", "UNICODE_STRING", MBX_T_UNICODE_STRING, 0 },
	{ "domain", "DOMAIN", MBX_T_DOMAIN, 0 },
};

const cogw_type *cogw_type_find(const char *name)
{
	for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
		if (!strcasecmp(name, types[i].name) || !strcasecmp(name, types[i].cia_name))
			return &types[i];
	return NULL;
}

const cogw_type *cogw_type_of(uint16_t type)
{
	for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
		if (types[i].type == type)
			return &types[i];
	return NULL;
}

const char *cogw_type_names(void)
{
	return "bool, u8, u16, u24, u32, u40, u48, u56, u64, i8, i16, i24, i32, i40, i48, i56, "
	       "i64, r32, r64, time, timediff, string, hex, unicode, domain (or the CiA names "
	       "UNSIGNED8, REAL32, VISIBLE_STRING, OCTET_STRING, DOMAIN, ...)";
}

static bool is_signed(uint16_t type)
{
	return type == MBX_T_INTEGER8 || type == MBX_T_INTEGER16 || type == MBX_T_INTEGER24 ||
	       type == MBX_T_INTEGER32 || type == MBX_T_INTEGER40 || type == MBX_T_INTEGER48 ||
	       type == MBX_T_INTEGER56 || type == MBX_T_INTEGER64;
}

static uint64_t le_get(const uint8_t *d, size_t n)
{
	uint64_t v = 0;
	for (size_t i = 0; i < n && i < 8; i++)
		v |= (uint64_t)d[i] << (8 * i);
	return v;
}

static void le_put(uint8_t *d, size_t n, uint64_t v)
{
	for (size_t i = 0; i < n && i < 8; i++)
		d[i] = (uint8_t)(v >> (8 * i));
}

/* The shortest %g text that reads back to the same value. */
static int real_text(double d, bool single, char *buf, size_t cap)
{
	for (int prec = single ? 6 : 15; prec <= (single ? 9 : 17); prec++) {
		int n = snprintf(buf, cap, "%.*g", prec, d);
		if (n < 0 || (size_t)n >= cap)
			return COGW_E_TRUNCATED;
		if (single ? strtof(buf, NULL) == (float)d : strtod(buf, NULL) == d)
			return n;
	}
	return (int)strlen(buf);
}

static int hex_text(const uint8_t *data, size_t len, char *out, size_t cap)
{
	if (cap < len * 3 + 1)
		return COGW_E_TRUNCATED;
	size_t off = 0;
	for (size_t i = 0; i < len; i++)
		off += (size_t)snprintf(out + off, cap - off, "%s%02x", i ? " " : "", data[i]);
	out[off] = '\0';
	return (int)off;
}

int cogw_value_format(uint16_t type, const uint8_t *data, size_t len, char *out, size_t cap)
{
	const cogw_type *t = cogw_type_of(type);
	int n;

	if (!t || (t->size && len != t->size) || !cap)
		return COGW_E_INVAL;
	switch (type) {
	case MBX_T_VISIBLE_STRING:
		if (cap < len + 1)
			return COGW_E_TRUNCATED;
		memcpy(out, data, len);
		out[len] = '\0';
		return (int)len;
	case MBX_T_OCTET_STRING:
	case MBX_T_UNICODE_STRING:
	case MBX_T_DOMAIN:
		return hex_text(data, len, out, cap);
	case MBX_T_BOOLEAN:
		n = snprintf(out, cap, "%s", data[0] ? "true" : "false");
		break;
	case MBX_T_REAL32: {
		float f;
		memcpy(&f, data, 4); /* little-endian host (proto.h refuses others) */
		return real_text(f, true, out, cap);
	}
	case MBX_T_REAL64: {
		double d;
		memcpy(&d, data, 8);
		return real_text(d, false, out, cap);
	}
	case MBX_T_TIME_OF_DAY:
	case MBX_T_TIME_DIFFERENCE:
		/* CiA 301 §7.1.6.5/6: ms after midnight (28 bits), then days */
		n = snprintf(out, cap, "%u %u", (unsigned)le_get(data + 4, 2),
			     (unsigned)(le_get(data, 4) & 0x0FFFFFFFu));
		break;
	default: {
		uint64_t v = le_get(data, len);
		if (is_signed(type) && len < 8 && (v >> (len * 8 - 1)) & 1u)
			v |= ~(((uint64_t)1 << (len * 8)) - 1); /* sign-extended */
		n = is_signed(type) ? snprintf(out, cap, "%" PRId64, (int64_t)v)
				    : snprintf(out, cap, "%" PRIu64, v);
	}
	}
	return n < 0 || (size_t)n >= cap ? COGW_E_TRUNCATED : n;
}

/* An integer of `size` bytes, decimal or 0x hex, in the type's range. */
static int parse_integer(const char *text, bool sign, unsigned size, uint64_t *out)
{
	unsigned bits = size * 8u;
	char *end;
	if (!*text || isspace((unsigned char)text[0]))
		return COGW_E_INVAL;
	errno = 0;
	if (sign) {
		long long v = strtoll(text, &end, 0);
		int64_t min = bits == 64 ? INT64_MIN : -((int64_t)1 << (bits - 1));
		int64_t max = bits == 64 ? INT64_MAX : ((int64_t)1 << (bits - 1)) - 1;
		if (*end)
			return COGW_E_INVAL;
		if (errno == ERANGE || v < min || v > max)
			return COGW_E_PARAM;
		*out = (uint64_t)v;
		return 0;
	}
	if (text[0] == '-')
		return COGW_E_PARAM;
	unsigned long long v = strtoull(text, &end, 0);
	if (*end)
		return COGW_E_INVAL;
	if (errno == ERANGE || (bits < 64 && v >> bits))
		return COGW_E_PARAM;
	*out = v;
	return 0;
}

/* "01 02 ff", "0102ff", "01:02:ff". */
static int parse_hex(const char *text, uint8_t *out, size_t cap, size_t *len)
{
	size_t n = 0;
	for (const char *p = text; *p;) {
		if (*p == ' ' || *p == ':') {
			p++;
			continue;
		}
		if (!isxdigit((unsigned char)p[0]) || !isxdigit((unsigned char)p[1]))
			return COGW_E_INVAL;
		if (n >= cap)
			return COGW_E_TRUNCATED;
		char byte[3] = { p[0], p[1], 0 };
		out[n++] = (uint8_t)strtoul(byte, NULL, 16);
		p += 2;
	}
	*len = n;
	return 0;
}

int cogw_value_parse(uint16_t type, const char *text, uint8_t *out, size_t cap, size_t *len)
{
	const cogw_type *t = cogw_type_of(type);
	uint64_t v = 0;
	int rc;

	if (!t || !text)
		return COGW_E_INVAL;
	if (t->size > cap)
		return COGW_E_TRUNCATED;
	switch (type) {
	case MBX_T_VISIBLE_STRING: {
		size_t n = strlen(text);
		if (n > cap)
			return COGW_E_TRUNCATED;
		memcpy(out, text, n);
		*len = n;
		return 0;
	}
	case MBX_T_OCTET_STRING:
	case MBX_T_UNICODE_STRING:
	case MBX_T_DOMAIN:
		return parse_hex(text, out, cap, len);
	case MBX_T_BOOLEAN:
		if (!strcmp(text, "1") || !strcasecmp(text, "true"))
			v = 1;
		else if (strcmp(text, "0") && strcasecmp(text, "false"))
			return COGW_E_INVAL;
		break;
	case MBX_T_REAL32:
	case MBX_T_REAL64: {
		char *end;
		double d = strtod(text, &end);
		if (end == text || *end || isspace((unsigned char)text[0]))
			return COGW_E_INVAL;
		if (!isfinite(d) || (type == MBX_T_REAL32 && fabs(d) > 3.4028234663852886e38))
			return COGW_E_PARAM;
		if (type == MBX_T_REAL32) {
			float f = (float)d;
			memcpy(out, &f, 4);
		} else {
			memcpy(out, &d, 8);
		}
		*len = t->size;
		return 0;
	}
	case MBX_T_TIME_OF_DAY:
	case MBX_T_TIME_DIFFERENCE: {
		unsigned days, ms;
		char extra;
		if (sscanf(text, "%u %u %c", &days, &ms, &extra) != 2)
			return COGW_E_INVAL;
		if (days > 0xFFFFu || ms > 0x0FFFFFFFu)
			return COGW_E_PARAM;
		le_put(out, 4, ms);
		le_put(out + 4, 2, days);
		*len = 6;
		return 0;
	}
	default:
		if ((rc = parse_integer(text, is_signed(type), t->size, &v)) < 0)
			return rc;
	}
	le_put(out, t->size, v);
	*len = t->size;
	return 0;
}
