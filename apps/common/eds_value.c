/* SPDX-License-Identifier: MIT */
/*
 * apps/common/eds_value.c - one value of an EDS/DCF: its data type, access,
 * encoding and limits, checked, and collected when it is to be written.
 */
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "apps/common/eds_read.h"
#include "apps/common/json_od.h"
#include "core/cdcf.h"

/* Objects that are commands or state, never configuration. */
static bool index_is_excluded(uint16_t index)
{
	switch (index) {
	case 0x1003: /* pre-defined error field: writing 0 clears it */
	case 0x1010: /* store parameters: "save" signature */
	case 0x1011: /* restore default parameters: "load" signature */
	case 0x1021: /* store EDS */
	case 0x1023: /* OS command */
	case 0x1F25: /* configuration request */
	case 0x1F50: /* program data */
	case 0x1F51: /* program control */
		return true;
	default:
		return false;
	}
}
/* CiA 306 AccessType to the CO_ACC_* flags (core/od.h); "rw" may also be
 * mapped, as the file does not say otherwise. */
int eds_parse_access(eds_ctx *c, const ini_key *k, uint8_t *access)
{
	static const struct {
		const char *name;
		uint8_t access;
	} names[] = { { "ro", CO_ACC_RO }, { "const", CO_ACC_CO }, { "wo", CO_ACC_WO },
		      { "rw", CO_ACC_RW }, { "rwr", CO_ACC_RWR },  { "rww", CO_ACC_RWW } };
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++)
		if (!strcasecmp(k->val, names[i].name)) {
			*access = names[i].access;
			return 0;
		}
	return eds_fail(c, k->line, "AccessType '%s': not one of ro, wo, rw, rwr, rww, const",
			k->val);
}

int eds_parse_uint_key(eds_ctx *c, const ini_key *k, uint64_t max, uint64_t *out)
{
	num_val v;
	int rc = eds_parse_int_expr(c, k, &v);
	if (rc)
		return rc;
	if ((v.neg && v.mag) || v.mag > max)
		return eds_fail(c, k->line, "%s '%s': out of range 0..%llu", k->key, k->val,
				(unsigned long long)max);
	*out = v.mag;
	return 0;
}

int eds_parse_type(eds_ctx *c, const ini_sec *s, co_type *t)
{
	const ini_key *k = eds_get_key(s, "DataType");
	uint64_t v;
	int rc;

	if (!k)
		return eds_fail(c, s->line, "[%s]: DataType missing", s->name);
	rc = eds_parse_uint_key(c, k, 0xFFFF, &v);
	if (rc)
		return rc;
	if (!co_type_is_valid((co_type)v))
		return eds_fail(c, k->line, "DataType 0x%04llX is not a CiA 301 basic data type",
				(unsigned long long)v);
	*t = (co_type)v;
	return 0;
}

int eds_add_var(eds_ctx *c, uint16_t index, uint8_t sub, unsigned line, uint8_t *data,
		uint32_t size)
{
	if (eds_grow((void **)&c->vars, &c->vcap, c->nvars + 1, sizeof(*c->vars))) {
		free(data);
		return -ENOMEM;
	}
	c->vars[c->nvars++] =
		(out_var){ .index = index, .sub = sub, .line = line, .data = data, .size = size };
	return 0;
}

/* A VISIBLE_STRING's characters checked. CiA 301 VISIBLE_STRING is
 * ISO 646 (20h..7Eh); device files carry tabs and UTF-8 (the CANopenNode
 * editor writes them), and python-canopen sends such text as it is: so do
 * we. */
static int check_visible(eds_ctx *c, const ini_key *k)
{
	for (const char *p = k->val; *p; p++) {
		unsigned char ch = (unsigned char)*p;
		bool control = ch < 0x20 || ch == 0x7F;
		if (ch >= 0x20 && ch < 0x7F)
			continue;
		if (c->strict && control)
			return eds_fail(c, k->line, "%s: control character in a VISIBLE_STRING",
					k->key);
		if (c->strict)
			continue; /* non-ASCII: taken as it is in strict reading too */
		eds_warn(c, k->line,
			 "%s: %s in a VISIBLE_STRING (CiA 301: 20h..7Eh); the bytes are sent "
			 "as they are",
			 k->key, control ? "control character" : "non-ASCII text");
		break;
	}
	return 0;
}

/* An OCTET_STRING or DOMAIN value: hex digits, blanks between them. */
static int encode_hex(eds_ctx *c, const ini_key *k, co_type t, uint8_t **data, uint32_t *size)
{
	const char *s = k->val;
	size_t digits = 0, o = 0;
	int hi = -1;
	uint8_t *b;

	for (const char *p = s; *p; p++) {
		if (*p == ' ' || *p == '\t')
			continue;
		if (eds_hexval((unsigned char)*p) < 0)
			return eds_fail(c, k->line, "%s '%.40s': %s value must be hex digits",
					k->key, s, co_type_to_string(t));
		digits++;
	}
	if (digits % 2)
		return eds_fail(c, k->line, "%s '%.40s': odd number of hex digits", k->key, s);
	b = malloc(digits / 2 ? digits / 2 : 1);
	if (!b)
		return -ENOMEM;
	for (const char *p = s; *p; p++) {
		int h = eds_hexval((unsigned char)*p);
		if (h < 0)
			continue;
		if (hi < 0) {
			hi = h;
		} else {
			b[o++] = (uint8_t)(hi << 4 | h);
			hi = -1;
		}
	}
	*data = b;
	*size = (uint32_t)o;
	return 0;
}

static int encode_bytes(eds_ctx *c, const ini_key *k, co_type t, uint8_t **data, uint32_t *size)
{
	const char *s = k->val;
	size_t n = strlen(s);
	long m;
	int rc;

	switch (t) {
	case CO_T_VISIBLE_STRING:
		if ((rc = check_visible(c, k)))
			return rc;
		if (!(*data = malloc(n)))
			return -ENOMEM;
		memcpy(*data, s, n);
		*size = (uint32_t)n;
		return 0;
	case CO_T_UNICODE_STRING:
		m = json_od_utf8_to_utf16le(s, NULL, 0);
		if (m < 0)
			return eds_fail(c, k->line, "%s: UNICODE_STRING is not valid UTF-8",
					k->key);
		if (!(*data = malloc((size_t)m)))
			return -ENOMEM;
		json_od_utf8_to_utf16le(s, *data, (uint32_t)m);
		*size = (uint32_t)m;
		return 0;
	case CO_T_OCTET_STRING:
	case CO_T_DOMAIN:
		return encode_hex(c, k, t, data, size);
	default:
		return eds_fail(c, k->line, "%s: values of %s are not supported in EDS/DCF files",
				k->key, co_type_to_string(t));
	}
}

/* A LowLimit/HighLimit key, or NULL when it is absent, empty or (read
 * leniently) not a number of the type: then it is not checked. */
static const ini_key *limit_key(eds_ctx *c, const var_spec *v, co_type t, const char *name,
				uint64_t *bits, int *rc)
{
	const ini_key *k = eds_get_key(v->sec, name);

	*rc = 0;
	if (!k || !*k->val)
		return NULL;
	*rc = eds_parse_num(c, k, t, bits);
	if (*rc) {
		*rc = eds_tolerate_failure(c, *rc, "the limit is not checked");
		return NULL;
	}
	return k;
}

static int limit_check(eds_ctx *c, const var_spec *v, co_type t, uint64_t bits)
{
	uint64_t lb = 0, hb = 0;
	int rc;
	const ini_key *lo = limit_key(c, v, t, "LowLimit", &lb, &rc), *hi;

	if (rc)
		return rc;
	hi = limit_key(c, v, t, "HighLimit", &hb, &rc);
	if (rc)
		return rc;
	if (lo && hi && eds_num_cmp(t, lb, hb) > 0) {
		if (c->strict)
			return eds_fail(c, hi->line,
					"HighLimit '%s' is below LowLimit '%s' (line %u)", hi->val,
					lo->val, lo->line);
		eds_warn(c, hi->line,
			 "HighLimit '%s' is below LowLimit '%s' (line %u): the limits are not "
			 "checked",
			 hi->val, lo->val, lo->line);
		return 0;
	}
	if (lo && eds_num_cmp(t, bits, lb) < 0)
		return eds_fail(c, v->value->line, "%s '%s' is below LowLimit '%s' (line %u)",
				v->value->key, v->value->val, lo->val, lo->line);
	if (hi && eds_num_cmp(t, bits, hb) > 0)
		return eds_fail(c, v->value->line, "%s '%s' is above HighLimit '%s' (line %u)",
				v->value->key, v->value->val, hi->val, hi->line);
	return 0;
}

/* The bytes of a value, checked against its type and limits. */
static int encode_value(eds_ctx *c, const var_spec *v, co_type t, uint8_t **data, uint32_t *size)
{
	uint32_t n = co_type_size(t);
	uint64_t bits;
	int rc;

	if (!n || t == CO_T_TIME_OF_DAY || t == CO_T_TIME_DIFFERENCE)
		return encode_bytes(c, v->value, t, data, size);
	if ((rc = eds_parse_num(c, v->value, t, &bits)) || (rc = limit_check(c, v, t, bits)))
		return rc;
	*data = malloc(n);
	if (!*data)
		return -ENOMEM;
	for (uint32_t i = 0; i < n; i++)
		(*data)[i] = (uint8_t)(bits >> (8 * i));
	*size = n;
	return 0;
}

/* A DCF's configured value of an entry the configuration writes: the
 * one kind of value whose loss would change what the device does. */
static bool value_is_configured(const var_spec *v, bool writable)
{
	/* ParameterValue, or an entry of a compact object's [XXXXValue] */
	return writable && !index_is_excluded(v->index) &&
	       strcasecmp(v->value->key, "DefaultValue") != 0;
}

/* Check one sub-object; collect its value if a configuration writes it.
 * A value that cannot be used is refused when it is configured, else
 * (read leniently) left out with a warning, as python-canopen leaves out
 * a DefaultValue it cannot convert. */
static void report_entry(const eds_ctx *c, const var_spec *v, co_type t, uint8_t access,
			 const uint8_t *data, uint32_t size)
{
	const eds_entry e = { .index = v->index,
			      .sub = v->sub,
			      .type = (uint16_t)t,
			      .access = access,
			      .value = data,
			      .size = size,
			      .line = v->value ? v->value->line : v->sec->line };
	if (c->on_entry)
		c->on_entry(c->entry_arg, &e);
}

int eds_do_var(eds_ctx *c, const var_spec *v, co_type t, uint8_t access)
{
	bool writable = access & CO_ACC_WRITE;
	uint8_t *data = NULL;
	uint32_t size = 0;
	int rc;

	if (!v->value) {
		if (writable)
			c->st.skipped++;
		report_entry(c, v, t, access, NULL, 0);
		return 0;
	}
	c->st.values++;
	rc = encode_value(c, v, t, &data, &size);
	if (rc == -EINVAL && !value_is_configured(v, writable) &&
	    !(rc = eds_tolerate_failure(c, rc, "the value is not used"))) {
		if (writable)
			c->st.skipped++;
		report_entry(c, v, t, access, NULL, 0);
		return 0;
	}
	if (rc)
		return rc;
	report_entry(c, v, t, access, data, size);
	if (!writable || index_is_excluded(v->index) || size == 0) {
		free(data);
		return 0;
	}
	return eds_add_var(c, v->index, v->sub, v->value->line, data, size);
}
