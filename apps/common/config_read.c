/* SPDX-License-Identifier: MIT */
/*
 * apps/common/config_read.c - the small typed readers every section of the
 * configuration uses (config_read.h): the message, the optional numbers,
 * flags and words of an object into struct fields.
 */
#include <stdarg.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "apps/common/config_read.h"
#include "apps/common/json_od.h"
#include "apps/common/json_util.h"

int cfg_fail(struct ctx *c, const char *path, const char *fmt, ...)
{
	char reason[256];
	va_list ap;

	va_start(ap, fmt);
	vsnprintf(reason, sizeof(reason), fmt, ap);
	va_end(ap);
	return json_util_fail(c->msg, sizeof(c->msg), path, "%s", reason);
}

/* ---- small typed readers into struct fields ----------------------------------- */

int cfg_opt_u32(struct ctx *c, const cJSON *o, const char *key, const char *path, cfg_range r,
		uint32_t *out)
{
	uint64_t v = *out;
	const json_at at = cfg_at(c, path);
	int rc = json_util_opt_uint(o, key, &at, r.min, r.max, &v);

	if (!rc)
		*out = (uint32_t)v;
	return rc;
}

int cfg_opt_u16(struct ctx *c, const cJSON *o, const char *key, const char *path, cfg_range r,
		uint16_t *out)
{
	uint32_t v = *out;
	int rc = cfg_opt_u32(c, o, key, path, r, &v);

	if (!rc)
		*out = (uint16_t)v;
	return rc;
}

int cfg_opt_u8(struct ctx *c, const cJSON *o, const char *key, const char *path, cfg_range r,
	       uint8_t *out)
{
	uint32_t v = *out;
	int rc = cfg_opt_u32(c, o, key, path, r, &v);

	if (!rc)
		*out = (uint8_t)v;
	return rc;
}

int cfg_opt_unsigned(struct ctx *c, const cJSON *o, const char *key, const char *path, cfg_range r,
		     unsigned *out)
{
	uint32_t v = *out;
	int rc = cfg_opt_u32(c, o, key, path, r, &v);

	if (!rc)
		*out = v;
	return rc;
}

int cfg_check_object(struct ctx *c, const cJSON *o, const char *path, const char *const *keys)
{
	const json_at at = cfg_at(c, path);

	return json_util_check_object(o, &at, keys);
}

/* Names that end up in queue names and logs: [A-Za-z0-9_-]. */
int cfg_check_name_chars(struct ctx *c, const char *path, const char *s)
{
	for (const char *p = s; *p; p++) {
		if ((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') ||
		    (*p >= '0' && *p <= '9') || *p == '_' || *p == '-')
			continue;
		return cfg_fail(c, path, "\"%s\" may contain only letters, digits, '_' and '-'", s);
	}
	return 0;
}

int cfg_opt_flag(struct ctx *c, const cJSON *o, const char *key, const char *path, cfg_flag f,
		 uint32_t *bits)
{
	bool b = f.def;
	const json_at at = cfg_at(c, path);
	int rc = json_util_opt_bool(o, key, &at, &b);

	if (!rc && b)
		*bits |= f.bit;
	return rc;
}

/* An UNSIGNED32 given as a number or a "0x..." string. */
int cfg_opt_u32_hex(struct ctx *c, const cJSON *o, const char *key, const char *path, uint32_t *out)
{
	const cJSON *v = json_util_get(o, key);
	char p[JSON_PATH_MAX];
	uint64_t u;
	int rc;
	const json_at at = cfg_at(c, p);

	if (!v)
		return 0;
	json_util_path_key(p, sizeof(p), path, key);
	if ((rc = json_util_uint(v, &at, 0, UINT32_MAX, true, &u)))
		return rc;
	*out = (uint32_t)u;
	return 0;
}
