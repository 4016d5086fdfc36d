/* SPDX-License-Identifier: MIT */
/*
 * apps/common/json_od.c - object definitions and values from JSON (see
 * json_od.h and docs/config.md).
 *
 * Every check happens here, before co_od_add(), so that the message can
 * name the JSON path and the values as the user wrote them; the core's own
 * checks (co_od_check_value) run as well when values are applied, so a
 * value the configuration accepts is one an SDO write would accept too.
 */
#include "apps/common/json_od.h"

#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "apps/common/json_util.h"
#include "core/sdo.h"

#define NAME_MAX_LEN 255u
#define SUB_MAX 254u

/* ---- names ----------------------------------------------------------------- */

static const co_type all_types[] = {
	CO_T_BOOLEAN,         CO_T_INTEGER8,     CO_T_INTEGER16,      CO_T_INTEGER32,
	CO_T_UNSIGNED8,       CO_T_UNSIGNED16,   CO_T_UNSIGNED32,     CO_T_REAL32,
	CO_T_VISIBLE_STRING,  CO_T_OCTET_STRING, CO_T_UNICODE_STRING, CO_T_TIME_OF_DAY,
	CO_T_TIME_DIFFERENCE, CO_T_DOMAIN,       CO_T_INTEGER24,      CO_T_REAL64,
	CO_T_INTEGER40,       CO_T_INTEGER48,    CO_T_INTEGER56,      CO_T_INTEGER64,
	CO_T_UNSIGNED24,      CO_T_UNSIGNED40,   CO_T_UNSIGNED48,     CO_T_UNSIGNED56,
	CO_T_UNSIGNED64,
};

bool json_od_type_from_string(const char *s, co_type *t)
{
	for (size_t i = 0; i < sizeof(all_types) / sizeof(all_types[0]); i++) {
		if (!strcmp(s, co_type_to_string(all_types[i]))) {
			*t = all_types[i];
			return true;
		}
	}
	return false;
}

static const struct {
	const char *word;
	uint16_t acc;
} access_words[] = {
	{ "ro", CO_ACC_RO },   { "wo", CO_ACC_WO },   { "rw", CO_ACC_RW },
	{ "rwr", CO_ACC_RWR }, { "rww", CO_ACC_RWW }, { "const", CO_ACC_CO },
};

bool json_od_access_from_string(const char *s, uint16_t *acc)
{
	for (size_t i = 0; i < sizeof(access_words) / sizeof(access_words[0]); i++) {
		if (!strcmp(s, access_words[i].word)) {
			*acc = access_words[i].acc;
			return true;
		}
	}
	return false;
}

static bool type_is_int(co_type t)
{
	return !co_type_is_variable(t) && !co_type_is_real(t) && t != CO_T_BOOLEAN &&
	       t != CO_T_TIME_OF_DAY && t != CO_T_TIME_DIFFERENCE;
}

/* ---- value encoding ---------------------------------------------------------- */

/* UTF-8 (what cJSON gives, \u escapes included) to UTF-16LE. */
long json_od_utf8_to_utf16le(const char *s, uint8_t *out, uint32_t cap)
{
	const unsigned char *p = (const unsigned char *)s;
	uint32_t n = 0;

	while (*p) {
		uint32_t cp;
		unsigned extra;

		if (*p < 0x80) {
			cp = *p;
			extra = 0;
		} else if ((*p & 0xE0) == 0xC0) {
			cp = *p & 0x1F;
			extra = 1;
		} else if ((*p & 0xF0) == 0xE0) {
			cp = *p & 0x0F;
			extra = 2;
		} else if ((*p & 0xF8) == 0xF0) {
			cp = *p & 0x07;
			extra = 3;
		} else {
			return -1;
		}
		p++;
		for (unsigned i = 0; i < extra; i++, p++) {
			if ((*p & 0xC0) != 0x80)
				return -1;
			cp = cp << 6 | (*p & 0x3F);
		}
		if (cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF))
			return -1;
		/* out NULL: count only. */
		if (cp >= 0x10000) {
			uint32_t v = cp - 0x10000;

			if (out && n + 4 > cap)
				return -2;
			if (out) {
				co_put_le(out + n, 2, 0xD800 | (v >> 10));
				co_put_le(out + n + 2, 2, 0xDC00 | (v & 0x3FF));
			}
			n += 4;
		} else {
			if (out && n + 2 > cap)
				return -2;
			if (out)
				co_put_le(out + n, 2, cp);
			n += 2;
		}
	}
	return (long)n;
}

static int parse_time(const cJSON *v, co_type t, const char *path, uint8_t *buf, char *err,
		      size_t errlen)
{
	static const char *const keys[] = { "ms", "days", NULL };
	uint64_t ms = 0, days = 0;
	int rc;
	const json_at at = { path, err, errlen };

	/* CiA 301 §7.1.6.5/6: 28 bits of ms after midnight (or of a
	 * difference), 4 reserved bits, then 16 bits of days (since
	 * 1984-01-01 for TIME_OF_DAY). */
	if (!cJSON_IsObject(v))
		return json_util_fail(err, errlen, path,
				      "expected {\"ms\": .., \"days\": ..} for %s, got %s",
				      co_type_to_string(t), json_util_kind(v));
	if ((rc = json_util_check_object(v, &at, keys)) ||
	    (rc = json_util_opt_uint(v, "ms", &at, 0, 0x0FFFFFFF, &ms)) ||
	    (rc = json_util_opt_uint(v, "days", &at, 0, 0xFFFF, &days)))
		return rc;
	co_put_le(buf, 4, ms);
	co_put_le(buf + 4, 2, days);
	return 0;
}

/* One parser per kind of type: the value v of type t at path into out. */
typedef int (*value_parser)(const cJSON *v, co_type t, const char *path, json_od_buf *out,
			    char *err, size_t errlen);

static int parse_boolean(const cJSON *v, co_type t, const char *path, json_od_buf *out, char *err,
			 size_t errlen)
{
	bool b;
	uint64_t u;
	int rc;
	const json_at at = { path, err, errlen };

	(void)t;
	if (cJSON_IsBool(v))
		b = cJSON_IsTrue(v);
	else if (cJSON_IsNumber(v)) {
		if ((rc = json_util_uint(v, &at, 0, 1, false, &u)))
			return rc;
		b = u != 0;
	} else
		return json_util_fail(err, errlen, path,
				      "expected true or false for BOOLEAN, got %s",
				      json_util_kind(v));
	out->buf[0] = b;
	out->len = 1;
	return 0;
}

static int parse_time_value(const cJSON *v, co_type t, const char *path, json_od_buf *out,
			    char *err, size_t errlen)
{
	int rc;

	if ((rc = parse_time(v, t, path, out->buf, err, errlen)))
		return rc;
	out->len = co_type_size(t);
	return 0;
}

static int parse_real(const cJSON *v, co_type t, const char *path, json_od_buf *out, char *err,
		      size_t errlen)
{
	double d;
	int rc;
	const json_at at = { path, err, errlen };

	if (!cJSON_IsNumber(v))
		return json_util_fail(err, errlen, path, "expected a number for %s, got %s",
				      co_type_to_string(t), json_util_kind(v));
	if ((rc = json_util_real(v, &at, &d)))
		return rc;
	if (t == CO_T_REAL32) {
		float f;
		uint32_t bits;

		if (fabs(d) > FLT_MAX)
			return json_util_fail(err, errlen, path, "%g is out of range for REAL32",
					      d);
		f = (float)d;
		memcpy(&bits, &f, 4);
		co_put_le(out->buf, 4, bits);
	} else {
		uint64_t bits;

		memcpy(&bits, &d, 8);
		co_put_le(out->buf, 8, bits);
	}
	out->len = co_type_size(t);
	return 0;
}

static int parse_integer(const cJSON *v, co_type t, const char *path, json_od_buf *out, char *err,
			 size_t errlen)
{
	uint32_t size = co_type_size(t);
	int rc;
	const json_at at = { path, err, errlen };

	if (!cJSON_IsNumber(v) && !cJSON_IsString(v))
		return json_util_fail(err, errlen, path, "expected an integer for %s, got %s",
				      co_type_to_string(t), json_util_kind(v));
	if (co_type_is_signed(t)) {
		int64_t lo = size == 8 ? INT64_MIN : -((int64_t)1 << (8 * size - 1));
		int64_t hi = size == 8 ? INT64_MAX : ((int64_t)1 << (8 * size - 1)) - 1;
		int64_t s;

		if ((rc = json_util_sint(v, &at, lo, hi, &s)))
			return rc;
		co_put_le(out->buf, size, (uint64_t)s);
	} else {
		uint64_t hi = size == 8 ? UINT64_MAX : ((uint64_t)1 << (8 * size)) - 1;
		uint64_t u;

		if ((rc = json_util_uint(v, &at, 0, hi, false, &u)))
			return rc;
		co_put_le(out->buf, size, u);
	}
	out->len = size;
	return 0;
}

static int parse_visible_string(const cJSON *v, co_type t, const char *path, json_od_buf *out,
				char *err, size_t errlen)
{
	size_t n;

	(void)t;
	if (!cJSON_IsString(v))
		return json_util_fail(err, errlen, path,
				      "expected a string for VISIBLE_STRING, got %s",
				      json_util_kind(v));
	n = strlen(v->valuestring);
	if (n > out->cap)
		return json_util_fail(err, errlen, path,
				      "string of %zu bytes is longer than max_size %u", n,
				      out->cap);
	memcpy(out->buf, v->valuestring, n);
	out->len = (uint32_t)n;
	return 0;
}

static int parse_unicode_string(const cJSON *v, co_type t, const char *path, json_od_buf *out,
				char *err, size_t errlen)
{
	long n;

	(void)t;
	if (!cJSON_IsString(v))
		return json_util_fail(err, errlen, path,
				      "expected a string for UNICODE_STRING, got %s",
				      json_util_kind(v));
	n = json_od_utf8_to_utf16le(v->valuestring, out->buf, out->cap);
	if (n == -1)
		return json_util_fail(err, errlen, path, "string is not valid UTF-8");
	if (n == -2)
		return json_util_fail(err, errlen, path,
				      "string is longer than max_size %u bytes (UTF-16)", out->cap);
	out->len = (uint32_t)n;
	return 0;
}

/* OCTET_STRING and DOMAIN: hex. */
static int parse_hex_bytes(const cJSON *v, co_type t, const char *path, json_od_buf *out, char *err,
			   size_t errlen)
{
	size_t n;
	int rc;
	const json_at at = { path, err, errlen };

	(void)t;
	if ((rc = json_util_hex(v, &at, out->buf, out->cap, &n)))
		return rc;
	out->len = (uint32_t)n;
	return 0;
}

static value_parser value_parser_of(co_type t)
{
	if (t == CO_T_BOOLEAN)
		return parse_boolean;
	if (t == CO_T_TIME_OF_DAY || t == CO_T_TIME_DIFFERENCE)
		return parse_time_value;
	if (co_type_is_real(t))
		return parse_real;
	if (type_is_int(t))
		return parse_integer;
	if (t == CO_T_VISIBLE_STRING)
		return parse_visible_string;
	if (t == CO_T_UNICODE_STRING)
		return parse_unicode_string;
	return parse_hex_bytes;
}

int json_od_parse_value(const cJSON *v, co_type t, const char *path, json_od_buf *out, char *err,
			size_t errlen)
{
	if (!co_type_is_valid(t))
		return json_util_fail(err, errlen, path, "invalid type");
	if (!co_type_is_variable(t) && out->cap < co_type_size(t))
		return json_util_fail(err, errlen, path, "no room for the value");
	return value_parser_of(t)(v, t, path, out, err, errlen);
}

int json_od_parse_index(const cJSON *v, const char *path, uint16_t *out, char *err, size_t errlen)
{
	uint64_t u;
	const json_at at = { path, err, errlen };
	int rc = json_util_uint(v, &at, 0x1000, 0xFFFF, true, &u);

	if (!rc)
		*out = (uint16_t)u;
	return rc;
}

/* Bytes a variable-type JSON value needs (before the max_size check), or
 * -1 when it is malformed (the parse reports why). */
static long var_value_len(const cJSON *v, co_type t)
{
	if (t == CO_T_VISIBLE_STRING)
		return cJSON_IsString(v) ? (long)strlen(v->valuestring) : -1;
	if (t == CO_T_UNICODE_STRING)
		return cJSON_IsString(v) ? json_od_utf8_to_utf16le(v->valuestring, NULL, 0) : -1;
	return json_util_hex_len(v);
}

/* Compare two numeric wire values of type t: <0, 0, >0. */
static int num_cmp(co_type t, const uint8_t *a, const uint8_t *b)
{
	uint32_t n = co_type_size(t);
	uint64_t ua = co_get_le(a, n), ub = co_get_le(b, n);

	if (t == CO_T_REAL32) {
		float fa, fb;
		uint32_t ba = (uint32_t)ua, bb = (uint32_t)ub;

		memcpy(&fa, &ba, 4);
		memcpy(&fb, &bb, 4);
		return fa < fb ? -1 : fa > fb;
	}
	if (t == CO_T_REAL64) {
		double da, db;

		memcpy(&da, &ua, 8);
		memcpy(&db, &ub, 8);
		return da < db ? -1 : da > db;
	}
	if (co_type_is_signed(t)) {
		unsigned sh = 64 - 8 * n;
		int64_t sa = (int64_t)(ua << sh) >> sh;
		int64_t sb = (int64_t)(ub << sh) >> sh;

		return sa < sb ? -1 : sa > sb;
	}
	return ua < ub ? -1 : ua > ub;
}

/* ---- object definitions -------------------------------------------------------- */

/* What one sub-index definition says; parsed fully before co_od_add. */
struct ent_spec {
	co_type type;
	uint16_t access;
	uint32_t max_size;
	const char *name;
	const cJSON *min, *max; /* JSON nodes, NULL = none */
	uint8_t min_b[8], max_b[8];
};

/* "type", "access", "pdo", "persist" and "name" of one definition. */
static int parse_kind(const cJSON *o, const char *path, struct ent_spec *s, char *err,
		      size_t errlen)
{
	char p[JSON_PATH_MAX];
	const cJSON *v;
	bool pdo = false, persist = false;
	int rc;
	const json_at at = { path, err, errlen };

	if ((rc = json_util_require(o, "type", &at, &v)))
		return rc;
	json_util_path_key(p, sizeof(p), path, "type");
	if (!cJSON_IsString(v))
		return json_util_fail(err, errlen, p,
				      "expected a type name like \"UNSIGNED16\", got %s",
				      json_util_kind(v));
	if (!json_od_type_from_string(v->valuestring, &s->type))
		return json_util_fail(err, errlen, p, "unknown type \"%.40s\"", v->valuestring);

	s->access = CO_ACC_RW;
	v = json_util_get(o, "access");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "access");
		if (!cJSON_IsString(v) || !json_od_access_from_string(v->valuestring, &s->access)) {
			char r[64];

			json_util_repr(v, r, sizeof(r));
			return json_util_fail(
				err, errlen, p,
				"unknown access %s (one of ro, wo, rw, rwr, rww, const)", r);
		}
	}
	if ((rc = json_util_opt_bool(o, "pdo", &at, &pdo)) ||
	    (rc = json_util_opt_bool(o, "persist", &at, &persist)))
		return rc;
	/* "pdo": mappable in the direction(s) the access allows. */
	if (pdo) {
		if (s->access & CO_ACC_READ)
			s->access |= CO_ACC_TPDO;
		if ((s->access & CO_ACC_WRITE) && !(s->access & CO_ACC_CONST))
			s->access |= CO_ACC_RPDO;
	}
	if (persist)
		s->access |= CO_ACC_PERSIST;

	v = json_util_get(o, "name");
	if (v) {
		json_util_path_key(p, sizeof(p), path, "name");
		if (!cJSON_IsString(v))
			return json_util_fail(err, errlen, p, "expected a string, got %s",
					      json_util_kind(v));
		if (strlen(v->valuestring) > NAME_MAX_LEN)
			return json_util_fail(err, errlen, p, "longer than %u bytes", NAME_MAX_LEN);
		s->name = v->valuestring;
	}
	return 0;
}

/* "max_size" of a string or domain; limits are refused there. */
static int parse_size(const cJSON *o, const char *path, struct ent_spec *s, char *err,
		      size_t errlen)
{
	char p[JSON_PATH_MAX];
	const cJSON *v = json_util_get(o, "max_size");
	uint64_t u;
	int rc;
	const json_at at = { p, err, errlen };

	if (s->min || s->max) {
		json_util_path_key(p, sizeof(p), path, s->min ? "min" : "max");
		return json_util_fail(err, errlen, p, "limits apply to numeric types only, not %s",
				      co_type_to_string(s->type));
	}
	if (!v)
		return 0;
	json_util_path_key(p, sizeof(p), path, "max_size");
	if ((rc = json_util_uint(v, &at, 1, JSON_OD_MAX_SIZE, false, &u)))
		return rc;
	s->max_size = (uint32_t)u;
	return 0;
}

/* "min" and "max" of an integer or real; "max_size" is refused there. */
static int parse_limits(const cJSON *o, const char *path, struct ent_spec *s, char *err,
			size_t errlen)
{
	char p[JSON_PATH_MAX];
	int rc;

	if (json_util_get(o, "max_size")) {
		json_util_path_key(p, sizeof(p), path, "max_size");
		return json_util_fail(err, errlen, p, "applies to strings and domains only, not %s",
				      co_type_to_string(s->type));
	}
	if ((s->min || s->max) && !type_is_int(s->type) && !co_type_is_real(s->type)) {
		json_util_path_key(p, sizeof(p), path, s->min ? "min" : "max");
		return json_util_fail(err, errlen, p,
				      "limits apply to integer and real types only, not %s",
				      co_type_to_string(s->type));
	}
	if (s->min) {
		json_util_path_key(p, sizeof(p), path, "min");
		if ((rc = json_od_parse_value(s->min, s->type, p, &(json_od_buf){ s->min_b, 8, 0 },
					      err, errlen)))
			return rc;
	}
	if (s->max) {
		json_util_path_key(p, sizeof(p), path, "max");
		if ((rc = json_od_parse_value(s->max, s->type, p, &(json_od_buf){ s->max_b, 8, 0 },
					      err, errlen)))
			return rc;
	}
	if (s->min && s->max && num_cmp(s->type, s->min_b, s->max_b) > 0) {
		char a[64], b[64];

		json_util_repr(s->min, a, sizeof(a));
		json_util_repr(s->max, b, sizeof(b));
		json_util_path_key(p, sizeof(p), path, "min");
		return json_util_fail(err, errlen, p, "min %s is greater than max %s", a, b);
	}
	return 0;
}

static int parse_common(const cJSON *o, const char *path, struct ent_spec *s, char *err,
			size_t errlen)
{
	int rc;

	memset(s, 0, sizeof(*s));
	if ((rc = parse_kind(o, path, s, err, errlen)))
		return rc;
	s->min = json_util_get(o, "min");
	s->max = json_util_get(o, "max");
	if (co_type_is_variable(s->type))
		return parse_size(o, path, s, err, errlen);
	return parse_limits(o, path, s, err, errlen);
}

/* Where one entry goes and how messages name it: path names the
 * definition, def_path its default. */
struct ent_place {
	co_od *od;
	uint16_t index;
	uint8_t sub;
	uint8_t obj_code;
	const char *path;
	const char *def_path;
};

/* The default of a string or domain into *buf (malloc'ed, or NULL when
 * there is none); capacity from max_size, else the default's length. */
static int var_default(const struct ent_place *at, const struct ent_spec *s, const cJSON *def,
		       co_od_desc *d, char *err, size_t errlen)
{
	uint32_t cap = s->max_size, len = 0;
	long need = def ? var_value_len(def, s->type) : 0;
	uint8_t *buf;
	int rc;

	if (!cap && def && need < 0) {
		/* Malformed default: let the parser say why. */
		uint8_t none;

		return json_od_parse_value(def, s->type, at->def_path,
					   &(json_od_buf){ &none, 0, 0 }, err, errlen);
	}
	if (!cap) {
		/* No max_size: the default's length is the capacity. */
		if (need <= 0) {
			char p[JSON_PATH_MAX];

			json_util_path_key(p, sizeof(p), at->path, "max_size");
			return json_util_fail(err, errlen, p,
					      "required for %s without a non-empty default",
					      co_type_to_string(s->type));
		}
		if ((uint64_t)need > JSON_OD_MAX_SIZE)
			need = JSON_OD_MAX_SIZE;
		cap = (uint32_t)need;
	}
	d->max_size = cap;
	if (!def)
		return 0;
	buf = malloc(cap ? cap : 1);
	if (!buf)
		return -ENOMEM;
	json_od_buf out = { buf, cap, 0 };
	rc = json_od_parse_value(def, s->type, at->def_path, &out, err, errlen);
	len = out.len;
	if (rc || !len) {
		free(buf);
		return rc;
	}
	d->def = buf;
	d->def_size = len;
	return 0;
}

/* The default (zero when def is NULL) against min, then max. */
static int check_bounds(const struct ent_place *at, const struct ent_spec *s, const cJSON *def,
			const uint8_t *num, char *err, size_t errlen)
{
	for (int upper = 0; upper < 2; upper++) {
		const cJSON *bound = upper ? s->max : s->min;
		int cmp;
		char a[64], b[64];

		if (!bound)
			continue;
		cmp = num_cmp(s->type, num, upper ? s->max_b : s->min_b);
		if (upper ? cmp <= 0 : cmp >= 0)
			continue;
		json_util_repr(def, a, sizeof(a));
		json_util_repr(bound, b, sizeof(b));
		if (!def)
			snprintf(a, sizeof(a), "0 (implicit)");
		return json_util_fail(err, errlen, def ? at->def_path : at->path,
				      "default %s is %s %s %s", a, upper ? "above" : "below",
				      upper ? "max" : "min", b);
	}
	return 0;
}

/* Add the entry at "at" as described by s with default JSON value def
 * (NULL = zero / empty). */
static int add_entry(const struct ent_place *at, struct ent_spec *s, const cJSON *def, char *err,
		     size_t errlen)
{
	uint8_t num[8] = { 0 };
	co_od_desc d = { .index = at->index,
			 .sub = at->sub,
			 .obj_code = at->obj_code,
			 .type = (uint8_t)s->type,
			 .access = s->access,
			 .name = s->name };
	int rc;

	if (co_type_is_variable(s->type)) {
		if ((rc = var_default(at, s, def, &d, err, errlen)))
			return rc;
	} else {
		if (def && (rc = json_od_parse_value(def, s->type, at->def_path,
						     &(json_od_buf){ num, 8, 0 }, err, errlen)))
			return rc;
		if ((rc = check_bounds(at, s, def, num, err, errlen)))
			return rc;
		d.def = num;
		d.def_size = co_type_size(s->type);
		d.min = s->min ? s->min_b : NULL;
		d.max = s->max ? s->max_b : NULL;
	}
	rc = co_od_add(at->od, &d, NULL);
	if (d.def && d.def != num)
		free((void *)d.def);
	if (rc == -EEXIST)
		return json_util_fail(err, errlen, at->path, "0x%04X:%02X is defined twice",
				      at->index, at->sub);
	if (rc == -ENOMEM)
		return rc;
	if (rc)
		return json_util_fail(err, errlen, at->path,
				      "the object dictionary refused 0x%04X:%02X (%s)", at->index,
				      at->sub, strerror(-rc));
	return 0;
}

static const char *const var_keys[] = { "index",    "object",  "name",    "type", "access",
					"pdo",      "persist", "default", "min",  "max",
					"max_size", "comment", NULL };
static const char *const array_keys[] = { "index", "object",  "name",     "type",    "access",
					  "pdo",   "persist", "length",   "default", "defaults",
					  "min",   "max",     "max_size", "comment", NULL };
static const char *const record_keys[] = { "index", "object", "name", "subs", "comment", NULL };
static const char *const sub_keys[] = { "sub",     "name", "type", "access",   "pdo",     "persist",
					"default", "min",  "max",  "max_size", "comment", NULL };

static int add_var(co_od *od, uint16_t index, const cJSON *o, const char *path, char *err,
		   size_t errlen)
{
	struct ent_spec s;
	char dp[JSON_PATH_MAX];
	int rc;
	const json_at at = { path, err, errlen };

	if ((rc = json_util_check_object(o, &at, var_keys)) ||
	    (rc = parse_common(o, path, &s, err, errlen)))
		return rc;
	json_util_path_key(dp, sizeof(dp), path, "default");
	return add_entry(&(struct ent_place){ od, index, 0, CO_OBJ_VAR, path, dp }, &s,
			 json_util_get(o, "default"), err, errlen);
}

/* Sub 0 of an ARRAY or RECORD at "at": n, the highest sub-index. */
static int add_sub0(const struct ent_place *at, uint8_t n, char *err, size_t errlen)
{
	co_od_entry *e;
	int rc = co_od_add_num(at->od, at->index, 0, CO_T_UNSIGNED8, CO_ACC_RO, n, &e);

	if (rc == -ENOMEM)
		return rc;
	if (rc)
		return json_util_fail(err, errlen, at->path, "0x%04X:00 is defined twice",
				      at->index);
	e->obj_code = at->obj_code;
	return 0;
}

static int add_array(co_od *od, uint16_t index, const cJSON *o, const char *path, char *err,
		     size_t errlen)
{
	struct ent_spec s;
	const cJSON *lv, *def = NULL, *defs;
	char p[JSON_PATH_MAX], dp[JSON_PATH_MAX];
	uint64_t n;
	int rc;
	const json_at at = { path, err, errlen };
	const json_at at_p = { p, err, errlen };

	if ((rc = json_util_check_object(o, &at, array_keys)) ||
	    (rc = parse_common(o, path, &s, err, errlen)) ||
	    (rc = json_util_require(o, "length", &at, &lv)))
		return rc;
	json_util_path_key(p, sizeof(p), path, "length");
	if ((rc = json_util_uint(lv, &at_p, 1, SUB_MAX, false, &n)))
		return rc;
	def = json_util_get(o, "default");
	defs = json_util_get(o, "defaults");
	if (def && defs) {
		json_util_path_key(p, sizeof(p), path, "defaults");
		return json_util_fail(err, errlen, p,
				      "give either \"default\" (all subs) or \"defaults\" (one per "
				      "sub), not both");
	}
	if (defs) {
		json_util_path_key(p, sizeof(p), path, "defaults");
		if (!cJSON_IsArray(defs))
			return json_util_fail(err, errlen, p, "expected an array, got %s",
					      json_util_kind(defs));
		if ((uint64_t)cJSON_GetArraySize(defs) != n)
			return json_util_fail(err, errlen, p, "has %d values, length is %llu",
					      cJSON_GetArraySize(defs), (unsigned long long)n);
	}
	if ((rc = add_sub0(&(struct ent_place){ od, index, 0, CO_OBJ_ARRAY, path, NULL },
			   (uint8_t)n, err, errlen)))
		return rc;
	for (unsigned i = 1; i <= n; i++) {
		const cJSON *dv = def;

		if (defs) {
			json_util_path_key(p, sizeof(p), path, "defaults");
			json_util_path_index(dp, sizeof(dp), p, i - 1);
			dv = cJSON_GetArrayItem(defs, (int)(i - 1));
		} else {
			json_util_path_key(dp, sizeof(dp), path, "default");
		}
		if ((rc = add_entry(
			     &(struct ent_place){ od, index, (uint8_t)i, CO_OBJ_ARRAY, path, dp },
			     &s, dv, err, errlen)))
			return rc;
	}
	return 0;
}

static int add_record(co_od *od, uint16_t index, const cJSON *o, const char *path, char *err,
		      size_t errlen)
{
	const cJSON *subs, *it;
	char sp[JSON_PATH_MAX], p[JSON_PATH_MAX], dp[JSON_PATH_MAX];
	uint8_t seen[SUB_MAX + 1] = { 0 };
	unsigned highest = 0;
	size_t i = 0;
	int rc;
	const json_at at = { path, err, errlen };
	const json_at at_p = { p, err, errlen };
	const json_at at_dp = { dp, err, errlen };

	if ((rc = json_util_check_object(o, &at, record_keys)) ||
	    (rc = json_util_require(o, "subs", &at, &subs)))
		return rc;
	json_util_path_key(sp, sizeof(sp), path, "subs");
	if (!cJSON_IsArray(subs) || cJSON_GetArraySize(subs) == 0)
		return json_util_fail(err, errlen, sp,
				      "expected a non-empty array of sub-index definitions");
	/* First pass: sub numbers, so that sub 0 (the highest sub-index,
	 * CiA 301 §7.4.3) is known before anything is added. */
	cJSON_ArrayForEach(it, subs)
	{
		const cJSON *sv;
		uint64_t sub;

		json_util_path_index(p, sizeof(p), sp, i++);
		if ((rc = json_util_check_object(it, &at_p, sub_keys)) ||
		    (rc = json_util_require(it, "sub", &at_p, &sv)))
			return rc;
		json_util_path_key(dp, sizeof(dp), p, "sub");
		if ((rc = json_util_uint(sv, &at_dp, 1, SUB_MAX, false, &sub)))
			return rc;
		if (seen[sub])
			return json_util_fail(err, errlen, dp, "sub-index %llu is defined twice",
					      (unsigned long long)sub);
		seen[sub] = 1;
		if (sub > highest)
			highest = (unsigned)sub;
	}
	if ((rc = add_sub0(&(struct ent_place){ od, index, 0, CO_OBJ_RECORD, path, NULL },
			   (uint8_t)highest, err, errlen)))
		return rc;
	i = 0;
	cJSON_ArrayForEach(it, subs)
	{
		struct ent_spec s;
		uint64_t sub = 0;

		json_util_path_index(p, sizeof(p), sp, i++);
		json_util_uint(json_util_get(it, "sub"), &at_p, 1, SUB_MAX, false, &sub);
		if ((rc = parse_common(it, p, &s, err, errlen)))
			return rc;
		json_util_path_key(dp, sizeof(dp), p, "default");
		if ((rc = add_entry(
			     &(struct ent_place){ od, index, (uint8_t)sub, CO_OBJ_RECORD, p, dp },
			     &s, json_util_get(it, "default"), err, errlen)))
			return rc;
	}
	return 0;
}

int json_od_add_objects(co_od *od, const cJSON *objects, const char *path_prefix, char *err,
			size_t errlen)
{
	const cJSON *o;
	char p[JSON_PATH_MAX], kp[JSON_PATH_MAX];
	size_t i = 0;
	int rc;
	const json_at at = { p, err, errlen };

	if (!cJSON_IsArray(objects))
		return json_util_fail(err, errlen, path_prefix,
				      "expected an array of object definitions, got %s",
				      json_util_kind(objects));
	cJSON_ArrayForEach(o, objects)
	{
		const cJSON *iv, *kind;
		uint16_t index;
		const char *k = "VAR";

		json_util_path_index(p, sizeof(p), path_prefix, i++);
		if (!cJSON_IsObject(o))
			return json_util_fail(err, errlen, p, "expected an object, got %s",
					      json_util_kind(o));
		if ((rc = json_util_require(o, "index", &at, &iv)))
			return rc;
		json_util_path_key(kp, sizeof(kp), p, "index");
		if ((rc = json_od_parse_index(iv, kp, &index, err, errlen)))
			return rc;
		if (co_od_has_index(od, index))
			return json_util_fail(err, errlen, kp,
					      "object 0x%04X already exists (a standard object or "
					      "defined twice; set values in \"values\")",
					      index);
		kind = json_util_get(o, "object");
		if (kind) {
			json_util_path_key(kp, sizeof(kp), p, "object");
			if (!cJSON_IsString(kind))
				return json_util_fail(
					err, errlen, kp,
					"expected \"VAR\", \"ARRAY\" or \"RECORD\", got %s",
					json_util_kind(kind));
			k = kind->valuestring;
		}
		if (!strcmp(k, "VAR"))
			rc = add_var(od, index, o, p, err, errlen);
		else if (!strcmp(k, "ARRAY"))
			rc = add_array(od, index, o, p, err, errlen);
		else if (!strcmp(k, "RECORD"))
			rc = add_record(od, index, o, p, err, errlen);
		else
			rc = json_util_fail(err, errlen, kp,
					    "unknown object code \"%.40s\" (VAR, ARRAY or RECORD)",
					    k);
		if (rc)
			return rc;
	}
	return 0;
}

/* ---- values -------------------------------------------------------------------- */

static const char *const value_keys[] = { "index", "sub", "value", "comment", NULL };

/* The "index" and "sub" of a value (o, at p): its entry in od. */
static int value_entry(co_od *od, const cJSON *o, const char *p, co_od_entry **e, char *err,
		       size_t errlen)
{
	char kp[JSON_PATH_MAX];
	const cJSON *iv, *sv;
	uint16_t index;
	uint64_t sub = 0;
	uint32_t abort = 0;
	int rc;
	const json_at at = { p, err, errlen };
	const json_at at_kp = { kp, err, errlen };

	if ((rc = json_util_require(o, "index", &at, &iv)))
		return rc;
	json_util_path_key(kp, sizeof(kp), p, "index");
	if ((rc = json_od_parse_index(iv, kp, &index, err, errlen)))
		return rc;
	if (!co_od_has_index(od, index))
		return json_util_fail(err, errlen, kp, "object 0x%04X does not exist", index);
	sv = json_util_get(o, "sub");
	if (sv) {
		json_util_path_key(kp, sizeof(kp), p, "sub");
		if ((rc = json_util_uint(sv, &at_kp, 0, 255, false, &sub)))
			return rc;
	}
	*e = co_od_find_ex(od, index, (uint8_t)sub, &abort);
	if (!*e)
		return json_util_fail(err, errlen, sv ? kp : p,
				      "object 0x%04X has no sub-index %llu", index,
				      (unsigned long long)sub);
	return 0;
}

/* The value vv (at kp, buf of len bytes) as e's new default, checked as a
 * run-time write would be. */
static int set_value(co_od_entry *e, const cJSON *vv, const char *kp, const json_od_buf *val,
		     char *err, size_t errlen)
{
	const uint8_t *buf = val->buf;
	uint32_t len = val->len;
	uint32_t abort = co_od_check_value(e, buf, len);
	int rc;

	/* an object with a write check (installed by the caller) refuses here
	 * what a run-time write would refuse */
	if (!abort && e->hooks && e->hooks->check_write) {
		co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL, .data = buf, .size = len };
		abort = e->hooks->check_write(e->hook_ctx, e, &a);
	}
	if (abort) {
		char r[64];

		json_util_repr(vv, r, sizeof(r));
		return json_util_fail(err, errlen, kp, "%s refused for 0x%04X:%02X (%s)", r,
				      e->index, (unsigned)e->sub, sdo_abort_to_string(abort));
	}
	rc = co_od_entry_set_default_bytes(e, buf, len);
	if (rc == -ENOMEM)
		return rc;
	if (rc)
		return json_util_fail(err, errlen, kp, "cannot store the value (%s)",
				      strerror(-rc));
	co_od_entry_reset(e);
	return 0;
}

static int apply_one(co_od *od, const cJSON *o, const char *p, uint32_t *key, char *err,
		     size_t errlen)
{
	char kp[JSON_PATH_MAX];
	const cJSON *vv;
	co_od_entry *e;
	uint32_t cap;
	uint8_t num[8];
	uint8_t *buf = num;
	int rc;
	const json_at at = { p, err, errlen };

	/* "index" is missing, then "value": the first of them is named */
	if ((rc = json_util_check_object(o, &at, value_keys)) ||
	    (rc = json_util_require(o, "index", &at, &vv)) ||
	    (rc = json_util_require(o, "value", &at, &vv)) ||
	    (rc = value_entry(od, o, p, &e, err, errlen)))
		return rc;
	*key = (uint32_t)e->index << 8 | (uint32_t)e->sub;

	json_util_path_key(kp, sizeof(kp), p, "value");
	cap = co_type_is_variable((co_type)e->type) ? e->max_size : 8;
	if (cap > sizeof(num)) {
		buf = malloc(cap);
		if (!buf)
			return -ENOMEM;
	}
	json_od_buf val = { buf, cap, 0 };
	rc = json_od_parse_value(vv, (co_type)e->type, kp, &val, err, errlen);
	if (!rc)
		rc = set_value(e, vv, kp, &val, err, errlen);
	if (buf != num)
		free(buf);
	return rc;
}

int json_od_apply_values(co_od *od, const cJSON *values, const char *path_prefix, char *err,
			 size_t errlen)
{
	const cJSON *o;
	char p[JSON_PATH_MAX];
	uint32_t *keys;
	size_t i = 0, n;
	int rc = 0;

	if (!cJSON_IsArray(values))
		return json_util_fail(
			err, errlen, path_prefix,
			"expected an array of {\"index\", \"sub\", \"value\"}, got %s",
			json_util_kind(values));
	n = (size_t)cJSON_GetArraySize(values);
	/* each entry may be set once: more values than entries is a file
	 * gone wrong (and the duplicate check below is quadratic) */
	if (n > co_od_count(od))
		return json_util_fail(err, errlen, path_prefix,
				      "%zu values, more than the %zu entries of the dictionary", n,
				      co_od_count(od));
	keys = calloc(n ? n : 1, sizeof(*keys));
	if (!keys)
		return -ENOMEM;
	cJSON_ArrayForEach(o, values)
	{
		json_util_path_index(p, sizeof(p), path_prefix, i);
		if (!cJSON_IsObject(o)) {
			rc = json_util_fail(err, errlen, p, "expected an object, got %s",
					    json_util_kind(o));
			break;
		}
		if ((rc = apply_one(od, o, p, &keys[i], err, errlen)))
			break;
		/* The same entry set twice is a typo or a merge accident:
		 * which one wins would depend on the order of the list. */
		for (size_t j = 0; j < i; j++) {
			if (keys[j] == keys[i]) {
				rc = json_util_fail(err, errlen, p,
						    "0x%04X:%02X is already set by %s[%zu]",
						    keys[i] >> 8, keys[i] & 0xFF, path_prefix, j);
				break;
			}
		}
		if (rc)
			break;
		i++;
	}
	free(keys);
	return rc;
}
