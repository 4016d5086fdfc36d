/* SPDX-License-Identifier: MIT */
/*
 * apps/common/json_util.c - strict cJSON helpers (see json_util.h).
 *
 * Why strict: a configuration typo ("hearbeat_ms") that is silently ignored
 * runs a line with defaults nobody asked for, and the first sign is a
 * missing heartbeat on site. So every object is checked for unknown and
 * duplicate keys (cJSON itself keeps duplicates and returns the first),
 * numbers must be integral where an integer is meant, and the 2^53 limit
 * of JSON numbers is enforced instead of silently rounding 64-bit values.
 */
#include "apps/common/json_util.h"

#include "apps/common/file_read.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int json_util_fail(char *err, size_t errlen, const char *path, const char *fmt, ...)
{
	char reason[256];
	va_list ap;

	va_start(ap, fmt);
	vsnprintf(reason, sizeof(reason), fmt, ap);
	va_end(ap);
	if (err && errlen)
		snprintf(err, errlen, "%s: %s", path && *path ? path : "(top)", reason);
	return -EINVAL;
}

int json_util_parse(const char *text, cJSON **out, char *err, size_t errlen)
{
	const char *end = NULL;
	cJSON *root;

	*out = NULL;
	root = cJSON_ParseWithOpts(text, &end, 1);
	if (!root) {
		unsigned line = 1, col = 1;
		const char *p;

		if (!end || end < text)
			end = text;
		for (p = text; p < end && *p; p++) {
			if (*p == '\n') {
				line++;
				col = 1;
			} else {
				col++;
			}
		}
		if (err && errlen)
			snprintf(err, errlen, "line %u column %u: invalid JSON", line, col);
		return -EINVAL;
	}
	*out = root;
	return 0;
}

void json_util_path_key(char *buf, size_t n, const char *path, const char *key)
{
	if (path && *path)
		snprintf(buf, n, "%s.%s", path, key);
	else
		snprintf(buf, n, "%s", key);
}

void json_util_path_index(char *buf, size_t n, const char *path, size_t i)
{
	snprintf(buf, n, "%s[%zu]", path ? path : "", i);
}

const char *json_util_kind(const cJSON *v)
{
	if (!v)
		return "nothing";
	if (cJSON_IsNumber(v))
		return "a number";
	if (cJSON_IsString(v))
		return "a string";
	if (cJSON_IsBool(v))
		return "a boolean";
	if (cJSON_IsNull(v))
		return "null";
	if (cJSON_IsArray(v))
		return "an array";
	if (cJSON_IsObject(v))
		return "an object";
	return "an invalid value";
}

cJSON *json_util_real_number(const char *text)
{
	char buf[64];

	if (strpbrk(text, ".eE") || strlen(text) + 3 > sizeof buf)
		return cJSON_CreateRaw(text);
	snprintf(buf, sizeof buf, "%s.0", text);
	return cJSON_CreateRaw(buf);
}

void json_util_repr(const cJSON *v, char *buf, size_t n)
{
	if (!v) {
		snprintf(buf, n, "nothing");
	} else if (cJSON_IsNumber(v)) {
		double d = v->valuedouble;

		if (d == floor(d) && fabs(d) <= JSON_EXACT_INT_MAX)
			snprintf(buf, n, "%.0f", d);
		else
			snprintf(buf, n, "%.17g", d);
	} else if (cJSON_IsString(v)) {
		size_t len = strlen(v->valuestring);

		if (len > 40)
			snprintf(buf, n, "\"%.37s...\"", v->valuestring);
		else
			snprintf(buf, n, "\"%s\"", v->valuestring);
	} else if (cJSON_IsTrue(v)) {
		snprintf(buf, n, "true");
	} else if (cJSON_IsFalse(v)) {
		snprintf(buf, n, "false");
	} else if (cJSON_IsNull(v)) {
		snprintf(buf, n, "null");
	} else if (cJSON_IsArray(v)) {
		snprintf(buf, n, "an array");
	} else {
		snprintf(buf, n, "an object");
	}
}

/* Levenshtein distance, capped: enough to say "did you mean". */
static unsigned edit_distance(const char *a, const char *b)
{
	size_t la = strlen(a), lb = strlen(b);
	unsigned row[33];

	if (la > 32 || lb > 32)
		return 99;
	for (size_t j = 0; j <= lb; j++)
		row[j] = (unsigned)j;
	for (size_t i = 1; i <= la; i++) {
		unsigned diag = row[0];

		row[0] = (unsigned)i;
		for (size_t j = 1; j <= lb; j++) {
			unsigned up = row[j];
			unsigned best = diag + (a[i - 1] != b[j - 1]);

			if (up + 1 < best)
				best = up + 1;
			if (row[j - 1] + 1 < best)
				best = row[j - 1] + 1;
			row[j] = best;
			diag = up;
		}
	}
	return row[lb];
}

int json_util_check_object(const cJSON *obj, const json_at *at, const char *const *allowed)
{
	char p[JSON_PATH_MAX];
	const cJSON *c, *d;

	if (!cJSON_IsObject(obj))
		return json_util_fail(at->err, at->errlen, at->path, "expected an object, got %s",
				      json_util_kind(obj));
	for (c = obj->child; c; c = c->next) {
		bool known = false;
		const char *hint = NULL;
		unsigned best = 3;

		json_util_path_key(p, sizeof(p), at->path, c->string);
		for (size_t i = 0; allowed[i]; i++) {
			unsigned dist;

			if (!strcmp(allowed[i], c->string)) {
				known = true;
				break;
			}
			dist = edit_distance(allowed[i], c->string);
			if (dist < best) {
				best = dist;
				hint = allowed[i];
			}
		}
		if (!known) {
			if (hint)
				return json_util_fail(at->err, at->errlen, p,
						      "unknown key (did you mean \"%s\"?)", hint);
			return json_util_fail(at->err, at->errlen, p, "unknown key");
		}
		for (d = obj->child; d != c; d = d->next)
			if (!strcmp(d->string, c->string))
				return json_util_fail(at->err, at->errlen, p, "duplicate key");
	}
	return 0;
}

const cJSON *json_util_get(const cJSON *obj, const char *key)
{
	return cJSON_GetObjectItemCaseSensitive(obj, key);
}

int json_util_require(const cJSON *obj, const char *key, const json_at *at, const cJSON **out)
{
	char p[JSON_PATH_MAX];

	*out = json_util_get(obj, key);
	if (*out)
		return 0;
	json_util_path_key(p, sizeof(p), at->path, key);
	return json_util_fail(at->err, at->errlen, p, "required key is missing");
}

static int digit_value(char c)
{
	if (c >= '0' && c <= '9')
		return c - '0';
	if (c >= 'a' && c <= 'f')
		return c - 'a' + 10;
	if (c >= 'A' && c <= 'F')
		return c - 'A' + 10;
	return 99;
}

/* Parse a whole string as an integer; false on any junk or overflow. */
static bool parse_int_string(const char *s, bool *neg, uint64_t *mag)
{
	unsigned base = 10;
	uint64_t v = 0;

	*neg = false;
	if (*s == '-' || *s == '+')
		*neg = *s++ == '-';
	if (s[0] == '0' && (s[1] == 'x' || s[1] == 'X')) {
		base = 16;
		s += 2;
	} else if (s[0] == '0' && s[1]) {
		base = 8;
		s++;
	}
	if (!*s)
		return false;
	for (; *s; s++) {
		int d = digit_value(*s);

		if (d >= (int)base)
			return false;
		if (v > (UINT64_MAX - (uint64_t)d) / base)
			return false;
		v = v * base + (uint64_t)d;
	}
	*mag = v;
	if (v == 0)
		*neg = false;
	return true;
}

int json_util_int(const cJSON *v, const json_at *at, bool *neg, uint64_t *mag)
{
	char r[64];

	if (cJSON_IsNumber(v)) {
		double d = v->valuedouble;

		json_util_repr(v, r, sizeof(r));
		if (!isfinite(d) || d != floor(d))
			return json_util_fail(at->err, at->errlen, at->path, "%s is not an integer",
					      r);
		if (fabs(d) > JSON_EXACT_INT_MAX)
			return json_util_fail(at->err, at->errlen, at->path,
					      "%s is beyond the exact range of JSON numbers; write "
					      "it as a string (\"0x...\")",
					      r);
		*neg = d < 0;
		*mag = (uint64_t)fabs(d);
		return 0;
	}
	if (cJSON_IsString(v)) {
		if (!parse_int_string(v->valuestring, neg, mag)) {
			json_util_repr(v, r, sizeof(r));
			return json_util_fail(at->err, at->errlen, at->path, "%s is not an integer",
					      r);
		}
		return 0;
	}
	return json_util_fail(at->err, at->errlen, at->path, "expected an integer, got %s",
			      json_util_kind(v));
}

int json_util_uint(const cJSON *v, const json_at *at, uint64_t min, uint64_t max, bool hex,
		   uint64_t *out)
{
	bool neg;
	uint64_t mag;
	char r[64];
	int rc = json_util_int(v, at, &neg, &mag);

	if (rc)
		return rc;
	if (neg || mag < min || mag > max) {
		json_util_repr(v, r, sizeof(r));
		if (hex)
			return json_util_fail(at->err, at->errlen, at->path,
					      "%s is out of range 0x%04llX..0x%04llX", r,
					      (unsigned long long)min, (unsigned long long)max);
		return json_util_fail(at->err, at->errlen, at->path,
				      "%s is out of range %llu..%llu", r, (unsigned long long)min,
				      (unsigned long long)max);
	}
	*out = mag;
	return 0;
}

int json_util_sint(const cJSON *v, const json_at *at, int64_t min, int64_t max, int64_t *out)
{
	bool neg;
	uint64_t mag;
	char r[64];
	int64_t val;
	int rc = json_util_int(v, at, &neg, &mag);

	if (rc)
		return rc;
	if (!neg && mag > (uint64_t)INT64_MAX)
		goto range;
	if (neg && mag > (uint64_t)INT64_MAX + 1u)
		goto range;
	val = neg ? (int64_t)(0 - mag) : (int64_t)mag;
	if (val < min || val > max)
		goto range;
	*out = val;
	return 0;
range:
	json_util_repr(v, r, sizeof(r));
	return json_util_fail(at->err, at->errlen, at->path, "%s is out of range %lld..%lld", r,
			      (long long)min, (long long)max);
}

int json_util_real(const cJSON *v, const json_at *at, double *out)
{
	if (!cJSON_IsNumber(v))
		return json_util_fail(at->err, at->errlen, at->path, "expected a number, got %s",
				      json_util_kind(v));
	if (!isfinite(v->valuedouble))
		return json_util_fail(at->err, at->errlen, at->path, "number is not finite");
	*out = v->valuedouble;
	return 0;
}

int json_util_bool(const cJSON *v, const json_at *at, bool *out)
{
	if (!cJSON_IsBool(v))
		return json_util_fail(at->err, at->errlen, at->path,
				      "expected true or false, got %s", json_util_kind(v));
	*out = cJSON_IsTrue(v);
	return 0;
}

int json_util_string(const cJSON *v, const json_at *at, size_t min_len, char *buf, size_t cap)
{
	size_t len;

	if (!cJSON_IsString(v))
		return json_util_fail(at->err, at->errlen, at->path, "expected a string, got %s",
				      json_util_kind(v));
	len = strlen(v->valuestring);
	if (len < min_len)
		return json_util_fail(at->err, at->errlen, at->path, "must not be empty");
	if (len >= cap)
		return json_util_fail(at->err, at->errlen, at->path,
				      "\"%.40s%s\" is too long (%zu bytes, at most %zu)",
				      v->valuestring, len > 40 ? "..." : "", len, cap - 1);
	memcpy(buf, v->valuestring, len + 1);
	return 0;
}

/* The json_at of obj's member key: its path "path.key" written into p. */
static json_at member_at(const json_at *at, const char *key, char *p, size_t n)
{
	json_util_path_key(p, n, at->path, key);
	return (json_at){ p, at->err, at->errlen };
}

int json_util_opt_uint(const cJSON *obj, const char *key, const json_at *at, uint64_t min,
		       uint64_t max, uint64_t *out)
{
	const cJSON *v = json_util_get(obj, key);
	char p[JSON_PATH_MAX];
	json_at member;

	if (!v)
		return 0;
	member = member_at(at, key, p, sizeof(p));
	return json_util_uint(v, &member, min, max, false, out);
}

int json_util_opt_sint(const cJSON *obj, const char *key, const json_at *at, int64_t min,
		       int64_t max, int64_t *out)
{
	const cJSON *v = json_util_get(obj, key);
	char p[JSON_PATH_MAX];
	json_at member;

	if (!v)
		return 0;
	member = member_at(at, key, p, sizeof(p));
	return json_util_sint(v, &member, min, max, out);
}

int json_util_opt_bool(const cJSON *obj, const char *key, const json_at *at, bool *out)
{
	const cJSON *v = json_util_get(obj, key);
	char p[JSON_PATH_MAX];
	json_at member;

	if (!v)
		return 0;
	member = member_at(at, key, p, sizeof(p));
	return json_util_bool(v, &member, out);
}

int json_util_opt_string(const cJSON *obj, const char *key, const json_at *at, size_t min_len,
			 char *buf, size_t cap)
{
	const cJSON *v = json_util_get(obj, key);
	char p[JSON_PATH_MAX];
	json_at member;

	if (!v)
		return 0;
	member = member_at(at, key, p, sizeof(p));
	return json_util_string(v, &member, min_len, buf, cap);
}

/* Decode into buf (NULL = count only). Returns bytes or -1. */
static long hex_decode(const char *s, uint8_t *buf, size_t cap)
{
	size_t n = 0;

	for (;;) {
		int hi, lo;

		while (*s == ' ')
			s++;
		if (!*s)
			break;
		hi = digit_value(s[0]);
		lo = s[1] ? digit_value(s[1]) : 99;
		if (hi > 15 || lo > 15)
			return -1;
		if (buf) {
			if (n >= cap)
				return -1;
			buf[n] = (uint8_t)(hi << 4 | lo);
		}
		n++;
		s += 2;
	}
	return (long)n;
}

long json_util_hex_len(const cJSON *v)
{
	if (!cJSON_IsString(v))
		return -1;
	return hex_decode(v->valuestring, NULL, 0);
}

int json_util_hex(const cJSON *v, const json_at *at, uint8_t *buf, size_t cap, size_t *len)
{
	long n;

	if (!cJSON_IsString(v))
		return json_util_fail(at->err, at->errlen, at->path,
				      "expected a hex string like \"01 02 ff\", got %s",
				      json_util_kind(v));
	n = json_util_hex_len(v);
	if (n < 0)
		return json_util_fail(
			at->err, at->errlen, at->path,
			"not a hex string (pairs of hex digits, optionally separated by spaces)");
	if ((size_t)n > cap)
		return json_util_fail(at->err, at->errlen, at->path,
				      "%ld bytes are longer than max_size %zu", n, cap);
	hex_decode(v->valuestring, buf, cap);
	*len = (size_t)n;
	return 0;
}

int json_util_opt_unsigned(const cJSON *obj, const char *key, const json_at *at, uint64_t min,
			   uint64_t max, unsigned *out)
{
	uint64_t u = *out;

	if (json_util_opt_uint(obj, key, at, min, max, &u))
		return -EINVAL;
	*out = (unsigned)u;
	return 0;
}

int json_util_load_text(const char *json, const char *source,
			int (*load)(void *ctx, const cJSON *root, char *err, size_t errlen),
			void *ctx, char *err, size_t errlen)
{
	cJSON *root = NULL;
	char why[512];
	int rc = json_util_parse(json, &root, why, sizeof why);

	if (rc == 0)
		rc = load(ctx, root, why, sizeof why);
	cJSON_Delete(root);
	if (rc)
		snprintf(err, errlen, "%s: %s", source, why);
	return rc;
}

int json_util_load_file(const char *path, size_t max,
			int (*load)(void *ctx, const cJSON *root, char *err, size_t errlen),
			void *ctx, char *err, size_t errlen)
{
	uint8_t *buf;
	size_t len;
	int rc = cogw_file_read(path, max, &buf, &len, err, errlen);

	if (rc)
		return rc == -ENOENT ? -ENOENT : -EIO;
	rc = json_util_load_text((const char *)buf, path, load, ctx, err, errlen);
	free(buf);
	return rc;
}
