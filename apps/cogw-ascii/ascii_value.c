/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-ascii/ascii_value.c - CiA 309-3 value texts. Every value is
 * checked completely before anything is sent: a typo must never reach a
 * device as a different number (the same rule as cogwctl's values).
 */
#include "apps/cogw-ascii/ascii_value.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "core/frame.h"

const ascii_type ascii_types[] = {
	{ "b", ASCII_K_BOOL, 1, true },
	{ "i8", ASCII_K_INT, 1, true },
	{ "i16", ASCII_K_INT, 2, true },
	{ "i32", ASCII_K_INT, 4, true },
	{ "i64", ASCII_K_INT, 8, true },
	{ "u8", ASCII_K_UINT, 1, true },
	{ "u16", ASCII_K_UINT, 2, true },
	{ "u32", ASCII_K_UINT, 4, true },
	{ "u64", ASCII_K_UINT, 8, true },
	{ "x8", ASCII_K_HEXINT, 1, false },
	{ "x16", ASCII_K_HEXINT, 2, false },
	{ "x32", ASCII_K_HEXINT, 4, false },
	{ "x64", ASCII_K_HEXINT, 8, false },
	{ "r32", ASCII_K_REAL32, 4, true },
	{ "r64", ASCII_K_REAL64, 8, true },
	{ "t", ASCII_K_TIME, 6, true },
	{ "td", ASCII_K_TIME, 6, true },
	{ "vs", ASCII_K_VSTRING, 0, true },
	{ "os", ASCII_K_BASE64, 0, true },
	{ "us", ASCII_K_BASE64, 0, true },
	{ "d", ASCII_K_BASE64, 0, true },
	{ "hex", ASCII_K_HEXBYTES, 0, false },
	{ NULL, 0, 0, false },
};

const ascii_type *ascii_type_find(const char *keyword, size_t len)
{
	for (const ascii_type *t = ascii_types; t->keyword; t++)
		if (strlen(t->keyword) == len && strncasecmp(t->keyword, keyword, len) == 0)
			return t;
	return NULL;
}

/* ---- numbers ---------------------------------------------------------------- */

static int hex_digit(char c)
{
	if (c >= '0' && c <= '9')
		return c - '0';
	if (c >= 'a' && c <= 'f')
		return c - 'a' + 10;
	if (c >= 'A' && c <= 'F')
		return c - 'A' + 10;
	return -1;
}

int ascii_number(const char *s, size_t n, uint64_t *out)
{
	unsigned base = 10;
	uint64_t v = 0;

	if (n >= 2 && s[0] == '0' && (s[1] == 'x' || s[1] == 'X')) {
		base = 16;
		s += 2;
		n -= 2;
	}
	if (n == 0)
		return -EINVAL;
	for (size_t i = 0; i < n; i++) {
		int d = base == 16 ? hex_digit(s[i])
				   : (s[i] >= '0' && s[i] <= '9' ? s[i] - '0' : -1);

		if (d < 0)
			return -EINVAL;
		if (v > (UINT64_MAX - (uint64_t)d) / base)
			return -ERANGE;
		v = v * base + (uint64_t)d;
	}
	*out = v;
	return 0;
}

static uint64_t umax_of(unsigned size)
{
	return size >= 8 ? UINT64_MAX : ((uint64_t)1 << (8 * size)) - 1;
}

static int encode_int(const ascii_type *t, const char *s, size_t n, uint8_t *buf)
{
	bool neg = n > 0 && s[0] == '-';
	uint64_t mag;
	int rc;

	if (n > 0 && (s[0] == '-' || s[0] == '+')) {
		s++;
		n--;
	}
	rc = ascii_number(s, n, &mag);
	if (rc)
		return rc;
	if (t->kind == ASCII_K_INT) {
		uint64_t lim = (uint64_t)1 << (8 * t->size - 1); /* |min| */

		if (neg ? mag > lim : mag > lim - 1)
			return -ERANGE;
		co_put_le(buf, t->size, neg ? (uint64_t)0 - mag : mag);
		return 0;
	}
	if ((neg && mag != 0) || mag > umax_of(t->size))
		return -ERANGE;
	co_put_le(buf, t->size, mag);
	return 0;
}

static int encode_real(const ascii_type *t, const char *s, size_t n, uint8_t *buf)
{
	char tmp[64];
	char *end;
	double d;

	if (n == 0 || n >= sizeof tmp)
		return -EINVAL;
	memcpy(tmp, s, n);
	tmp[n] = '\0';
	errno = 0;
	d = strtod(tmp, &end);
	if (*end != '\0')
		return -EINVAL;
	if (t->kind == ASCII_K_REAL32) {
		float f = (float)d;
		uint32_t bits;

		if (isfinite(d) && !isfinite(f))
			return -ERANGE;
		memcpy(&bits, &f, 4);
		co_put_le(buf, 4, bits);
	} else {
		uint64_t bits;

		if (errno == ERANGE && isinf(d))
			return -ERANGE;
		memcpy(&bits, &d, 8);
		co_put_le(buf, 8, bits);
	}
	return 0;
}

/* "<days> <ms>": CiA 301 TIME_OF_DAY / TIME_DIFFERENCE, ms in 28 bits
 * (below one day), then 4 reserved bits, then days in 16 bits. */
#define MS_PER_DAY 86400000u

static int encode_time(const char *s, size_t n, uint8_t *buf)
{
	size_t i = 0;
	uint64_t days, ms;
	int rc;

	while (i < n && s[i] != ' ' && s[i] != '\t')
		i++;
	if (i == n)
		return -EINVAL;
	rc = ascii_number(s, i, &days);
	if (rc)
		return rc;
	while (i < n && (s[i] == ' ' || s[i] == '\t'))
		i++;
	rc = ascii_number(s + i, n - i, &ms);
	if (rc)
		return rc;
	if (days > 0xFFFF || ms >= MS_PER_DAY)
		return -ERANGE;
	co_put_le(buf, 4, ms);
	co_put_le(buf + 4, 2, days);
	return 0;
}

static int encode_hexbytes(const char *s, size_t n, uint8_t *buf, size_t cap, size_t *len)
{
	size_t out = 0;

	for (size_t i = 0; i < n;) {
		if (s[i] == ' ' || s[i] == '\t') {
			i++;
			continue;
		}
		if (i + 1 >= n)
			return -EINVAL;
		int hi = hex_digit(s[i]), lo = hex_digit(s[i + 1]);

		if (hi < 0 || lo < 0)
			return -EINVAL;
		if (out >= cap)
			return -E2BIG;
		buf[out++] = (uint8_t)(hi << 4 | lo);
		i += 2;
	}
	*len = out;
	return 0;
}

int ascii_value_encode(const ascii_type *t, const char *text, size_t n, uint8_t *buf, size_t cap,
		       size_t *len)
{
	int rc;

	if (t->size && cap < t->size)
		return -E2BIG;
	switch (t->kind) {
	case ASCII_K_BOOL:
		if ((n == 1 && text[0] == '0') || (n == 5 && strncasecmp(text, "false", 5) == 0))
			buf[0] = 0;
		else if ((n == 1 && text[0] == '1') ||
			 (n == 4 && strncasecmp(text, "true", 4) == 0))
			buf[0] = 1;
		else
			return -EINVAL;
		*len = 1;
		return 0;
	case ASCII_K_INT:
	case ASCII_K_UINT:
	case ASCII_K_HEXINT:
		rc = encode_int(t, text, n, buf);
		break;
	case ASCII_K_REAL32:
	case ASCII_K_REAL64:
		rc = encode_real(t, text, n, buf);
		break;
	case ASCII_K_TIME:
		rc = encode_time(text, n, buf);
		break;
	case ASCII_K_VSTRING:
		if (n > cap)
			return -E2BIG;
		memcpy(buf, text, n);
		*len = n;
		return 0;
	case ASCII_K_BASE64:
		return ascii_base64_decode(text, n, buf, cap, len);
	case ASCII_K_HEXBYTES:
		return encode_hexbytes(text, n, buf, cap, len);
	default:
		return -EINVAL;
	}
	if (rc == 0)
		*len = t->size;
	return rc;
}

/* ---- text of values ---------------------------------------------------------- */

size_t ascii_value_text_max(const ascii_type *t, size_t len)
{
	switch (t->kind) {
	case ASCII_K_VSTRING:
		return 2 * len + 3;
	case ASCII_K_BASE64:
		return (len + 2) / 3 * 4 + 1;
	case ASCII_K_HEXBYTES:
		return 3 * len + 1;
	default:
		return 48;
	}
}

static long format_real(const ascii_type *t, const uint8_t *data, char *out, size_t cap)
{
	/* the shortest %g precision that reads back to the same bits */
	for (int prec = 1; prec <= 17; prec++) {
		int n;

		if (t->kind == ASCII_K_REAL32) {
			uint32_t bits = (uint32_t)co_get_le(data, 4);
			float f, back;

			memcpy(&f, &bits, 4);
			n = snprintf(out, cap, "%.*g", prec, (double)f);
			back = strtof(out, NULL);
			if (memcmp(&back, &f, 4) == 0 || isnan(f))
				return n;
		} else {
			uint64_t bits = co_get_le(data, 8);
			double d, back;

			memcpy(&d, &bits, 8);
			n = snprintf(out, cap, "%.*g", prec, d);
			back = strtod(out, NULL);
			if (memcmp(&back, &d, 8) == 0 || isnan(d))
				return n;
		}
	}
	return (long)strlen(out);
}

long ascii_value_format(const ascii_type *t, const uint8_t *data, size_t len, char *out, size_t cap)
{
	size_t n = 0;

	if (t->size && len != t->size)
		return -EBADMSG;
	if (cap < ascii_value_text_max(t, len))
		return -E2BIG;
	switch (t->kind) {
	case ASCII_K_BOOL:
		return snprintf(out, cap, "%u", data[0] ? 1u : 0u);
	case ASCII_K_INT: {
		uint64_t v = co_get_le(data, t->size);
		unsigned shift = 64 - 8u * t->size;
		int64_t s = (int64_t)(v << shift) >> shift; /* sign-extend */

		return snprintf(out, cap, "%" PRId64, s);
	}
	case ASCII_K_UINT:
		return snprintf(out, cap, "%" PRIu64, co_get_le(data, t->size));
	case ASCII_K_HEXINT:
		return snprintf(out, cap, "0x%0*" PRIX64, 2 * t->size, co_get_le(data, t->size));
	case ASCII_K_REAL32:
	case ASCII_K_REAL64:
		return format_real(t, data, out, cap);
	case ASCII_K_TIME:
		return snprintf(out, cap, "%u %u", (unsigned)co_get_le(data + 4, 2),
				(unsigned)(co_get_le(data, 4) & 0x0FFFFFFFu));
	case ASCII_K_VSTRING:
		/* NUL (a C string's terminator, often sent along), CR and LF
		 * are dropped: an answer is one line and never carries a byte
		 * the gateway refuses as input (os or hex give every byte) */
		out[n++] = '"';
		for (size_t i = 0; i < len; i++) {
			if (data[i] == '\0' || data[i] == '\r' || data[i] == '\n')
				continue;
			if (data[i] == '"')
				out[n++] = '"';
			out[n++] = (char)data[i];
		}
		out[n++] = '"';
		out[n] = '\0';
		return (long)n;
	case ASCII_K_BASE64:
		return (long)ascii_base64_encode(data, len, out);
	case ASCII_K_HEXBYTES:
		for (size_t i = 0; i < len; i++)
			n += (size_t)snprintf(out + n, cap - n, i ? " %02X" : "%02X", data[i]);
		out[n] = '\0';
		return (long)n;
	}
	return -EINVAL;
}

/* ---- base64 (RFC 2045 alphabet, '=' padding) ------------------------------------ */

static const char b64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

size_t ascii_base64_encode(const uint8_t *data, size_t len, char *out)
{
	size_t n = 0;

	for (size_t i = 0; i < len; i += 3) {
		uint32_t v = (uint32_t)data[i] << 16;
		size_t rest = len - i;

		if (rest > 1)
			v |= (uint32_t)data[i + 1] << 8;
		if (rest > 2)
			v |= data[i + 2];
		out[n++] = b64[v >> 18 & 63];
		out[n++] = b64[v >> 12 & 63];
		out[n++] = rest > 1 ? b64[v >> 6 & 63] : '=';
		out[n++] = rest > 2 ? b64[v & 63] : '=';
	}
	out[n] = '\0';
	return n;
}

static int b64_value(char c)
{
	const char *p = c ? strchr(b64, c) : NULL;

	return p ? (int)(p - b64) : -1;
}

int ascii_base64_decode(const char *s, size_t n, uint8_t *buf, size_t cap, size_t *len)
{
	size_t out = 0;

	if (n % 4)
		return -EINVAL;
	for (size_t i = 0; i < n; i += 4) {
		int v[4];
		unsigned pad = 0;

		for (unsigned k = 0; k < 4; k++) {
			if (s[i + k] == '=' && i + 4 == n && k >= 2) {
				v[k] = 0;
				pad++;
				continue;
			}
			if (pad) /* a character after '=' */
				return -EINVAL;
			v[k] = b64_value(s[i + k]);
			if (v[k] < 0)
				return -EINVAL;
		}
		uint32_t w = (uint32_t)v[0] << 18 | (uint32_t)v[1] << 12 | (uint32_t)v[2] << 6 |
			     (uint32_t)v[3];

		if (out + 3 - pad > cap)
			return -E2BIG;
		buf[out++] = (uint8_t)(w >> 16);
		if (pad < 2)
			buf[out++] = (uint8_t)(w >> 8);
		if (pad < 1)
			buf[out++] = (uint8_t)w;
	}
	*len = out;
	return 0;
}
