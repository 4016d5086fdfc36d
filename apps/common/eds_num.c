/* SPDX-License-Identifier: MIT */
/*
 * apps/common/eds_num.c - the numbers of an EDS/DCF: integer literals and
 * $NODEID expressions, reals, their bits in a CiA 301 data type, and the
 * comparison of two values of a type.
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

/* ---- numbers ------------------------------------------------------------------- */

/* A literal: [+-] then 0x<hex>, 0<octal> or <decimal>. *pattern is set for
 * hex and octal (a signed type may take them as a bit pattern). */
static int parse_literal(const char *s, bool *neg, uint64_t *mag, bool *pattern)
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
	*pattern = base != 10;
	if (!*s)
		return -1;
	for (; *s; s++) {
		int d = eds_hexval((unsigned char)*s);
		if (d < 0 || (unsigned)d >= base)
			return -1;
		if (v > (UINT64_MAX - (unsigned)d) / base)
			return -2;
		v = v * base + (unsigned)d;
	}
	*mag = v;
	return 0;
}

/* An integer expression: literal, $NODEID, $NODEID+literal, literal+$NODEID. */
int eds_parse_int_expr(eds_ctx *c, const ini_key *k, num_val *out)
{
	char buf[128];
	char *terms[3];
	int nterms = 0, nodes = 0, lits = 0;
	size_t n = strlen(k->val);

	if (n >= sizeof(buf))
		return eds_fail(c, k->line, "%s: value too long for a number", k->key);
	memcpy(buf, k->val, n + 1);
	/* split at '+' that is not a leading sign */
	terms[nterms++] = buf;
	for (char *p = buf + 1; *p; p++) {
		if (*p == '+') {
			if (nterms == 2)
				return eds_fail(c, k->line, "%s '%s': more than two terms", k->key,
						k->val);
			*p = '\0';
			terms[nterms++] = p + 1;
		}
	}
	memset(out, 0, sizeof(*out));
	for (int i = 0; i < nterms; i++) {
		char *t = eds_trim(terms[i], terms[i] + strlen(terms[i]));
		if (!strcasecmp(t, "$NODEID")) {
			if (nodes++)
				return eds_fail(c, k->line, "%s '%s': $NODEID twice", k->key,
						k->val);
			c->node_id_missing = !c->node_id;
			if (!c->node_id)
				return eds_fail(
					c, k->line,
					"%s '%s': $NODEID needs a node id (none given and no "
					"[DeviceComissioning] NodeID)",
					k->key, k->val);
			continue;
		}
		if (strchr(t, '$'))
			return eds_fail(c, k->line,
					"%s '%s': bad expression (only $NODEID, '+' and numbers)",
					k->key, k->val);
		num_val lit;
		int rc = parse_literal(t, &lit.neg, &lit.mag, &lit.pattern);
		if (rc == -2)
			return eds_fail(c, k->line, "%s '%s': number too large", k->key, k->val);
		if (rc)
			return eds_fail(c, k->line,
					"%s '%s': not a number (decimal, 0x hex or 0 octal)",
					k->key, k->val);
		lits++;
		*out = lit;
	}
	if (lits > 1)
		return eds_fail(c, k->line, "%s '%s': bad expression (two numbers)", k->key,
				k->val);
	if (nodes) {
		if (out->neg && out->mag)
			return eds_fail(c, k->line, "%s '%s': $NODEID with a negative number",
					k->key, k->val);
		if (out->mag > UINT64_MAX - c->node_id)
			return eds_fail(c, k->line, "%s '%s': number too large", k->key, k->val);
		out->neg = false;
		out->mag += c->node_id;
	}
	return 0;
}

/* Range-check an integer for type t and give its bit pattern. */
static int int_to_bits(eds_ctx *c, const ini_key *k, co_type t, const num_val *v, uint64_t *bits)
{
	unsigned w = co_type_size(t) * 8;
	uint64_t umax = w == 64 ? UINT64_MAX : (UINT64_C(1) << w) - 1;

	if (t == CO_T_BOOLEAN)
		umax = 1;
	if (!co_type_is_signed(t)) {
		if (v->neg && v->mag)
			return eds_fail(c, k->line, "%s '%s': negative value for %s", k->key,
					k->val, co_type_to_string(t));
		if (v->mag > umax)
			return eds_fail(c, k->line, "%s '%s': out of range for %s (max %llu)",
					k->key, k->val, co_type_to_string(t),
					(unsigned long long)umax);
		*bits = v->mag;
		return 0;
	}
	uint64_t smax = umax >> 1; /* 2^(w-1) - 1 */
	if (v->neg) {
		if (v->mag > smax + 1)
			return eds_fail(c, k->line, "%s '%s': out of range for %s", k->key, k->val,
					co_type_to_string(t));
		*bits = (~v->mag + 1) & umax;
		return 0;
	}
	if (v->mag <= smax || (v->pattern && v->mag <= umax)) {
		*bits = v->mag;
		return 0;
	}
	return eds_fail(c, k->line, "%s '%s': out of range for %s", k->key, k->val,
			co_type_to_string(t));
}

static int parse_real(eds_ctx *c, const ini_key *k, co_type t, uint64_t *bits)
{
	const char *s = k->val;
	char *end;
	double d;

	if ((s[0] == '0' && (s[1] == 'x' || s[1] == 'X'))) {
		num_val v;
		int rc = parse_literal(s, &v.neg, &v.mag, &v.pattern);
		if (rc)
			return eds_fail(c, k->line, "%s '%s': not a hex bit pattern", k->key, s);
		if (t == CO_T_REAL32 && v.mag > UINT32_MAX)
			return eds_fail(c, k->line,
					"%s '%s': REAL32 bit pattern wider than 32 bits", k->key,
					s);
		*bits = v.mag;
		return 0;
	}
	errno = 0;
	d = strtod(s, &end);
	if (end == s || *end || strchr(s, 'x') || strchr(s, 'X'))
		return eds_fail(c, k->line, "%s '%s': not a number for %s", k->key, s,
				co_type_to_string(t));
	if (errno == ERANGE || !isfinite(d))
		return eds_fail(c, k->line, "%s '%s': out of range for %s", k->key, s,
				co_type_to_string(t));
	if (t == CO_T_REAL32) {
		float f;
		uint32_t u;
		if (fabs(d) > FLT_MAX)
			return eds_fail(c, k->line, "%s '%s': out of range for REAL32", k->key, s);
		f = (float)d;
		memcpy(&u, &f, 4);
		*bits = u;
	} else {
		memcpy(bits, &d, 8);
	}
	return 0;
}

/* Numeric value of key k as a bit pattern of type t. */
int eds_parse_num(eds_ctx *c, const ini_key *k, co_type t, uint64_t *bits)
{
	num_val v;
	int rc;

	if (co_type_is_real(t))
		return parse_real(c, k, t, bits);
	rc = eds_parse_int_expr(c, k, &v);
	return rc ? rc : int_to_bits(c, k, t, &v, bits);
}

int eds_num_cmp(co_type t, uint64_t a, uint64_t b)
{
	if (co_type_is_real(t)) {
		double x, y;
		if (t == CO_T_REAL32) {
			uint32_t ua = (uint32_t)a, ub = (uint32_t)b;
			float fa, fb;
			memcpy(&fa, &ua, 4);
			memcpy(&fb, &ub, 4);
			x = fa;
			y = fb;
		} else {
			memcpy(&x, &a, 8);
			memcpy(&y, &b, 8);
		}
		return x < y ? -1 : x > y;
	}
	if (co_type_is_signed(t)) {
		unsigned sh = 64 - co_type_size(t) * 8;
		int64_t x = (int64_t)(a << sh) >> sh, y = (int64_t)(b << sh) >> sh;
		return x < y ? -1 : x > y;
	}
	return a < b ? -1 : a > b;
}
