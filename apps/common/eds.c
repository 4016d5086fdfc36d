/* SPDX-License-Identifier: MIT */
/*
 * apps/common/eds.c - CiA 306 EDS/DCF reader and its conversion to a
 * concise DCF (the contract is in eds.h).
 *
 * Three passes: (1) INI text to sections and keys, every line numbered;
 * (2) sections sorted so duplicates sit side by side and every lookup is
 * a binary search (a device file has ~1000 sections; the fuzzer feeds
 * many more); (3) objects walked in index order, every value parsed and
 * checked against its data type and limits - also values that will not
 * be written, because a file with a broken value is a broken file - and
 * the writable ones collected, then emitted in the order a slave accepts
 * them (PDO parameters in the CiA 301 re-mapping order).
 */
#include "apps/common/eds.h"

#include <errno.h>
#include <fcntl.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "apps/common/file_read.h"
#include "apps/common/json_od.h"
#include "core/cdcf.h"
#include "core/od.h"

enum sec_kind {
	SEC_OTHER = 0, /* FileInfo, DeviceInfo, object lists, ... */
	SEC_OBJ,       /* [XXXX] */
	SEC_SUB,       /* [XXXXsubY] */
	SEC_NAME,      /* [XXXXName] (CompactSubObj names) */
	SEC_VALUE,     /* [XXXXValue] (CompactSubObj values in a DCF) */
	SEC_DENOT,     /* [XXXXDenotation] */
	SEC_LINKS,     /* [XXXXObjectLinks] */
};

typedef struct ini_key {
	const char *key;
	const char *val;
	unsigned line;
} ini_key;

typedef struct ini_sec {
	const char *name;
	unsigned line;
	enum sec_kind kind;
	uint16_t index;
	uint8_t sub;
	ini_key *keys;
	size_t nkeys, cap;
} ini_sec;

/* One value to write. */
typedef struct out_var {
	uint16_t index;
	uint8_t sub;
	unsigned line; /* line of the value */
	uint8_t *data;
	uint32_t size;
} out_var;

typedef struct eds_ctx {
	const char *file;
	char *text;
	ini_sec *secs;
	size_t nsecs, cap;
	ini_sec **sorted;
	uint8_t node_id;
	out_var *vars;
	size_t nvars, vcap;
	out_var *emit; /* output order (shallow copies of vars) */
	size_t nemit, ecap;
	eds_stats st;
	bool strict;
	bool node_id_missing; /* a refusal for want of an input, not a file fault */
	eds_warning_fn on_warning;
	void *warning_arg;
	eds_entry_fn on_entry;
	void *entry_arg;
	char msg[512]; /* the refusal, "file:line: reason", copied to err */
} eds_ctx;

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

/* "file:line: " and the reason into buf. */
static void vformat(const eds_ctx *c, char *buf, size_t size, unsigned line, const char *fmt,
		    va_list ap)
{
	int n = snprintf(buf, size, "%s:%u: ", c->file, line);

	if (n >= 0 && (size_t)n < size)
		vsnprintf(buf + n, size - (size_t)n, fmt, ap);
}

static int fail(eds_ctx *c, unsigned line, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static int fail(eds_ctx *c, unsigned line, const char *fmt, ...)
{
	va_list ap;

	va_start(ap, fmt);
	vformat(c, c->msg, sizeof(c->msg), line, fmt, ap);
	va_end(ap);
	return -EINVAL;
}

/* One complete warning text ("file:line: reason"). */
static void warn_text(eds_ctx *c, const char *text)
{
	if (!c->st.warnings++)
		/* cut to the stats' field: the callback still gets it whole */
		snprintf(c->st.first_warning, sizeof(c->st.first_warning), "%.*s",
			 (int)sizeof(c->st.first_warning) - 1, text);
	if (c->on_warning)
		c->on_warning(c->warning_arg, text);
}

static void vwarn(eds_ctx *c, unsigned line, const char *fmt, va_list ap)
{
	char text[600];

	vformat(c, text, sizeof(text), line, fmt, ap);
	warn_text(c, text);
}

static void warn(eds_ctx *c, unsigned line, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static void warn(eds_ctx *c, unsigned line, const char *fmt, ...)
{
	va_list ap;

	va_start(ap, fmt);
	vwarn(c, line, fmt, ap);
	va_end(ap);
}

/* Inconsistent but usable: a warning, or a refusal when reading strictly. */
static int tolerate(eds_ctx *c, unsigned line, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static int tolerate(eds_ctx *c, unsigned line, const char *fmt, ...)
{
	va_list ap;

	va_start(ap, fmt);
	if (c->strict)
		vformat(c, c->msg, sizeof(c->msg), line, fmt, ap);
	else
		vwarn(c, line, fmt, ap);
	va_end(ap);
	return c->strict ? -EINVAL : 0;
}

/* A refusal (rc, reason in c->msg) turned into a warning that says what
 * is left out instead - when reading leniently. */
static int tolerate_failure(eds_ctx *c, int rc, const char *left_out)
{
	char text[sizeof(c->msg) + 80];

	if (rc != -EINVAL || c->strict || c->node_id_missing)
		return rc;
	snprintf(text, sizeof(text), "%s: %s", c->msg, left_out);
	c->msg[0] = '\0';
	warn_text(c, text);
	return 0;
}

static int grow(void **p, size_t *cap, size_t need, size_t elem)
{
	size_t ncap;
	void *np;

	if (need <= *cap)
		return 0;
	ncap = *cap ? *cap * 2 : 16;
	while (ncap < need)
		ncap *= 2;
	np = realloc(*p, ncap * elem);
	if (!np)
		return -ENOMEM;
	*p = np;
	*cap = ncap;
	return 0;
}

/* ---- pass 1: INI text ------------------------------------------------------ */

static char *trim(char *s, char *end)
{
	while (s < end && (*s == ' ' || *s == '\t'))
		s++;
	while (end > s && (end[-1] == ' ' || end[-1] == '\t' || end[-1] == '\r'))
		end--;
	*end = '\0';
	return s;
}

static int hexval(int ch)
{
	if (ch >= '0' && ch <= '9')
		return ch - '0';
	if (ch >= 'a' && ch <= 'f')
		return ch - 'a' + 10;
	if (ch >= 'A' && ch <= 'F')
		return ch - 'A' + 10;
	return -1;
}

static void classify(ini_sec *s)
{
	const char *n = s->name;
	unsigned v = 0;

	s->kind = SEC_OTHER;
	for (int i = 0; i < 4; i++) {
		int h = hexval((unsigned char)n[i]);
		if (h < 0)
			return;
		v = v << 4 | (unsigned)h;
	}
	n += 4;
	s->index = (uint16_t)v;
	if (!*n) {
		s->kind = SEC_OBJ;
	} else if (!strncasecmp(n, "sub", 3)) {
		const char *d = n + 3;
		unsigned sub = 0;
		size_t nd = strlen(d);
		if (nd < 1 || nd > 2)
			return; /* checked by the caller: "sub" with a bad number */
		for (size_t i = 0; i < nd; i++) {
			int h = hexval((unsigned char)d[i]);
			if (h < 0)
				return;
			sub = sub << 4 | (unsigned)h;
		}
		s->sub = (uint8_t)sub;
		s->kind = SEC_SUB;
	} else if (!strcasecmp(n, "Name")) {
		s->kind = SEC_NAME;
	} else if (!strcasecmp(n, "Value")) {
		s->kind = SEC_VALUE;
	} else if (!strcasecmp(n, "Denotation")) {
		s->kind = SEC_DENOT;
	} else if (!strcasecmp(n, "ObjectLinks")) {
		s->kind = SEC_LINKS;
	}
}

/* An inline comment: ';' after white space, as the INI readers of
 * python-canopen and the CANopenNode editor take it (CiA 306 has comment
 * lines only). Cut off when reading leniently. */
static void cut_inline_comment(char *s)
{
	if (!*s)
		return;
	for (char *p = s + 1; *p; p++)
		if (*p == ';' && (p[-1] == ' ' || p[-1] == '\t')) {
			*p = '\0';
			trim(s, p);
			return;
		}
}

static int parse_ini(eds_ctx *c, size_t len)
{
	char *p = c->text, *end = c->text + len;
	ini_sec *cur = NULL;
	unsigned line = 0;

	/* a UTF-8 byte order mark, as Windows editors write it */
	if (!c->strict && len >= 3 && !memcmp(p, "\xEF\xBB\xBF", 3))
		p += 3;
	while (p < end) {
		char *nl = memchr(p, '\n', (size_t)(end - p));
		char *le = nl ? nl : end;
		char *s;

		line++;
		if (memchr(p, '\0', (size_t)(le - p)))
			return fail(c, line, "NUL byte: not a text file");
		s = trim(p, le);
		p = nl ? nl + 1 : end;
		if (!*s || *s == ';' || *s == '#')
			continue;
		if (*s == '[') {
			size_t n = strlen(s);
			char *name;

			if (s[n - 1] != ']' && !c->strict) {
				cut_inline_comment(s);
				n = strlen(s);
			}
			if (s[n - 1] != ']')
				return fail(c, line, "section header without closing ']'");
			name = trim(s + 1, s + n - 1);
			if (!*name)
				return fail(c, line, "empty section name");
			if (grow((void **)&c->secs, &c->cap, c->nsecs + 1, sizeof(*c->secs)))
				return -ENOMEM;
			cur = &c->secs[c->nsecs++];
			memset(cur, 0, sizeof(*cur));
			cur->name = name;
			cur->line = line;
			classify(cur);
			if (cur->kind == SEC_OTHER && strlen(name) > 4 &&
			    hexval((unsigned char)name[0]) >= 0 &&
			    hexval((unsigned char)name[1]) >= 0 &&
			    hexval((unsigned char)name[2]) >= 0 &&
			    hexval((unsigned char)name[3]) >= 0 && !strncasecmp(name + 4, "sub", 3))
				return fail(c, line,
					    "[%s]: sub-index must be 1 or 2 hex digits (00..FF)",
					    name);
			continue;
		}
		char *eq = strchr(s, '=');
		if (!eq)
			return fail(c, line, "expected [section] or key=value, got '%.40s'", s);
		if (!cur)
			return fail(c, line, "key=value before the first [section]");
		char *key = trim(s, eq);
		char *val = trim(eq + 1, eq + 1 + strlen(eq + 1));
		if (!c->strict)
			cut_inline_comment(val);
		if (!*key)
			return fail(c, line, "no key before '='");
		for (size_t i = 0; i < cur->nkeys; i++)
			if (!strcasecmp(cur->keys[i].key, key))
				return fail(c, line,
					    "duplicate key '%s' in [%s] (first at line %u)", key,
					    cur->name, cur->keys[i].line);
		if (grow((void **)&cur->keys, &cur->cap, cur->nkeys + 1, sizeof(*cur->keys)))
			return -ENOMEM;
		cur->keys[cur->nkeys++] = (ini_key){ .key = key, .val = val, .line = line };
	}
	return 0;
}

/* ---- pass 2: sorted sections ------------------------------------------------ */

static int sec_cmp(const ini_sec *a, const ini_sec *b)
{
	if ((a->kind == SEC_OTHER) != (b->kind == SEC_OTHER))
		return a->kind == SEC_OTHER ? -1 : 1;
	if (a->kind == SEC_OTHER)
		return strcasecmp(a->name, b->name);
	if (a->index != b->index)
		return a->index < b->index ? -1 : 1;
	if (a->kind != b->kind)
		return a->kind < b->kind ? -1 : 1;
	if (a->sub != b->sub)
		return a->sub < b->sub ? -1 : 1;
	return 0;
}

static int sec_qcmp(const void *a, const void *b)
{
	const ini_sec *x = *(ini_sec *const *)a, *y = *(ini_sec *const *)b;
	int r = sec_cmp(x, y);
	/* equal keys: file order, so the later one is reported */
	return r ? r : (x->line < y->line ? -1 : x->line > y->line);
}

static int sort_sections(eds_ctx *c)
{
	c->sorted = malloc((c->nsecs ? c->nsecs : 1) * sizeof(*c->sorted));
	if (!c->sorted)
		return -ENOMEM;
	for (size_t i = 0; i < c->nsecs; i++)
		c->sorted[i] = &c->secs[i];
	qsort(c->sorted, c->nsecs, sizeof(*c->sorted), sec_qcmp);
	for (size_t i = 1; i < c->nsecs; i++)
		if (!sec_cmp(c->sorted[i - 1], c->sorted[i]))
			return fail(c, c->sorted[i]->line,
				    "duplicate section [%s] (first at line %u)", c->sorted[i]->name,
				    c->sorted[i - 1]->line);
	return 0;
}

static ini_sec *find_sec(const eds_ctx *c, enum sec_kind kind, uint16_t index, uint8_t sub,
			 const char *name)
{
	ini_sec key = { .name = name, .kind = kind, .index = index, .sub = sub };
	size_t lo = 0, hi = c->nsecs;

	while (lo < hi) {
		size_t mid = lo + (hi - lo) / 2;
		int r = sec_cmp(c->sorted[mid], &key);
		if (!r)
			return c->sorted[mid];
		if (r < 0)
			lo = mid + 1;
		else
			hi = mid;
	}
	return NULL;
}

/* Position of the first sorted section at or after (kind, index, 0). */
static size_t lower_bound(const eds_ctx *c, enum sec_kind kind, uint16_t index)
{
	ini_sec key = { .kind = kind, .index = index };
	size_t lo = 0, hi = c->nsecs;

	while (lo < hi) {
		size_t mid = lo + (hi - lo) / 2;
		if (sec_cmp(c->sorted[mid], &key) < 0)
			lo = mid + 1;
		else
			hi = mid;
	}
	return lo;
}

static const ini_key *get_key(const ini_sec *s, const char *key)
{
	for (size_t i = 0; i < s->nkeys; i++)
		if (!strcasecmp(s->keys[i].key, key))
			return &s->keys[i];
	return NULL;
}

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
		int d = hexval((unsigned char)*s);
		if (d < 0 || (unsigned)d >= base)
			return -1;
		if (v > (UINT64_MAX - (unsigned)d) / base)
			return -2;
		v = v * base + (unsigned)d;
	}
	*mag = v;
	return 0;
}

typedef struct num_val {
	bool neg;
	uint64_t mag;
	bool pattern;
} num_val;

/* An integer expression: literal, $NODEID, $NODEID+literal, literal+$NODEID. */
static int parse_int_expr(eds_ctx *c, const ini_key *k, num_val *out)
{
	char buf[128];
	char *terms[3];
	int nterms = 0, nodes = 0, lits = 0;
	size_t n = strlen(k->val);

	if (n >= sizeof(buf))
		return fail(c, k->line, "%s: value too long for a number", k->key);
	memcpy(buf, k->val, n + 1);
	/* split at '+' that is not a leading sign */
	terms[nterms++] = buf;
	for (char *p = buf + 1; *p; p++) {
		if (*p == '+') {
			if (nterms == 2)
				return fail(c, k->line, "%s '%s': more than two terms", k->key,
					    k->val);
			*p = '\0';
			terms[nterms++] = p + 1;
		}
	}
	memset(out, 0, sizeof(*out));
	for (int i = 0; i < nterms; i++) {
		char *t = trim(terms[i], terms[i] + strlen(terms[i]));
		if (!strcasecmp(t, "$NODEID")) {
			if (nodes++)
				return fail(c, k->line, "%s '%s': $NODEID twice", k->key, k->val);
			c->node_id_missing = !c->node_id;
			if (!c->node_id)
				return fail(c, k->line,
					    "%s '%s': $NODEID needs a node id (none given and no "
					    "[DeviceComissioning] NodeID)",
					    k->key, k->val);
			continue;
		}
		if (strchr(t, '$'))
			return fail(c, k->line,
				    "%s '%s': bad expression (only $NODEID, '+' and numbers)",
				    k->key, k->val);
		num_val lit;
		int rc = parse_literal(t, &lit.neg, &lit.mag, &lit.pattern);
		if (rc == -2)
			return fail(c, k->line, "%s '%s': number too large", k->key, k->val);
		if (rc)
			return fail(c, k->line,
				    "%s '%s': not a number (decimal, 0x hex or 0 octal)", k->key,
				    k->val);
		lits++;
		*out = lit;
	}
	if (lits > 1)
		return fail(c, k->line, "%s '%s': bad expression (two numbers)", k->key, k->val);
	if (nodes) {
		if (out->neg && out->mag)
			return fail(c, k->line, "%s '%s': $NODEID with a negative number", k->key,
				    k->val);
		if (out->mag > UINT64_MAX - c->node_id)
			return fail(c, k->line, "%s '%s': number too large", k->key, k->val);
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
			return fail(c, k->line, "%s '%s': negative value for %s", k->key, k->val,
				    co_type_to_string(t));
		if (v->mag > umax)
			return fail(c, k->line, "%s '%s': out of range for %s (max %llu)", k->key,
				    k->val, co_type_to_string(t), (unsigned long long)umax);
		*bits = v->mag;
		return 0;
	}
	uint64_t smax = umax >> 1; /* 2^(w-1) - 1 */
	if (v->neg) {
		if (v->mag > smax + 1)
			return fail(c, k->line, "%s '%s': out of range for %s", k->key, k->val,
				    co_type_to_string(t));
		*bits = (~v->mag + 1) & umax;
		return 0;
	}
	if (v->mag <= smax || (v->pattern && v->mag <= umax)) {
		*bits = v->mag;
		return 0;
	}
	return fail(c, k->line, "%s '%s': out of range for %s", k->key, k->val,
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
			return fail(c, k->line, "%s '%s': not a hex bit pattern", k->key, s);
		if (t == CO_T_REAL32 && v.mag > UINT32_MAX)
			return fail(c, k->line, "%s '%s': REAL32 bit pattern wider than 32 bits",
				    k->key, s);
		*bits = v.mag;
		return 0;
	}
	errno = 0;
	d = strtod(s, &end);
	if (end == s || *end || strchr(s, 'x') || strchr(s, 'X'))
		return fail(c, k->line, "%s '%s': not a number for %s", k->key, s,
			    co_type_to_string(t));
	if (errno == ERANGE || !isfinite(d))
		return fail(c, k->line, "%s '%s': out of range for %s", k->key, s,
			    co_type_to_string(t));
	if (t == CO_T_REAL32) {
		float f;
		uint32_t u;
		if (fabs(d) > FLT_MAX)
			return fail(c, k->line, "%s '%s': out of range for REAL32", k->key, s);
		f = (float)d;
		memcpy(&u, &f, 4);
		*bits = u;
	} else {
		memcpy(bits, &d, 8);
	}
	return 0;
}

/* Numeric value of key k as a bit pattern of type t. */
static int parse_num(eds_ctx *c, const ini_key *k, co_type t, uint64_t *bits)
{
	num_val v;
	int rc;

	if (co_type_is_real(t))
		return parse_real(c, k, t, bits);
	rc = parse_int_expr(c, k, &v);
	return rc ? rc : int_to_bits(c, k, t, &v, bits);
}

static int num_cmp(co_type t, uint64_t a, uint64_t b)
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

/* ---- pass 3: objects -------------------------------------------------------- */

/* A sub-object as read from one section (or from a compact object). */
typedef struct var_spec {
	uint16_t index;
	uint8_t sub;
	const ini_sec *sec;   /* where DataType/AccessType/limits live */
	const ini_key *value; /* ParameterValue or DefaultValue; NULL = none */
	const char *where;    /* section name for messages */
} var_spec;

/* CiA 306 AccessType to the CO_ACC_* flags (core/od.h); "rw" may also be
 * mapped, as the file does not say otherwise. */
static int parse_access(eds_ctx *c, const ini_key *k, uint8_t *access)
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
	return fail(c, k->line, "AccessType '%s': not one of ro, wo, rw, rwr, rww, const", k->val);
}

static int parse_uint_key(eds_ctx *c, const ini_key *k, uint64_t max, uint64_t *out)
{
	num_val v;
	int rc = parse_int_expr(c, k, &v);
	if (rc)
		return rc;
	if ((v.neg && v.mag) || v.mag > max)
		return fail(c, k->line, "%s '%s': out of range 0..%llu", k->key, k->val,
			    (unsigned long long)max);
	*out = v.mag;
	return 0;
}

static int parse_type(eds_ctx *c, const ini_sec *s, co_type *t)
{
	const ini_key *k = get_key(s, "DataType");
	uint64_t v;
	int rc;

	if (!k)
		return fail(c, s->line, "[%s]: DataType missing", s->name);
	rc = parse_uint_key(c, k, 0xFFFF, &v);
	if (rc)
		return rc;
	if (!co_type_is_valid((co_type)v))
		return fail(c, k->line, "DataType 0x%04llX is not a CiA 301 basic data type",
			    (unsigned long long)v);
	*t = (co_type)v;
	return 0;
}

static int add_var(eds_ctx *c, uint16_t index, uint8_t sub, unsigned line, uint8_t *data,
		   uint32_t size)
{
	if (grow((void **)&c->vars, &c->vcap, c->nvars + 1, sizeof(*c->vars))) {
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
			return fail(c, k->line, "%s: control character in a VISIBLE_STRING",
				    k->key);
		if (c->strict)
			continue; /* non-ASCII: taken as it is in strict reading too */
		warn(c, k->line,
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
		if (hexval((unsigned char)*p) < 0)
			return fail(c, k->line, "%s '%.40s': %s value must be hex digits", k->key,
				    s, co_type_to_string(t));
		digits++;
	}
	if (digits % 2)
		return fail(c, k->line, "%s '%.40s': odd number of hex digits", k->key, s);
	b = malloc(digits / 2 ? digits / 2 : 1);
	if (!b)
		return -ENOMEM;
	for (const char *p = s; *p; p++) {
		int h = hexval((unsigned char)*p);
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
			return fail(c, k->line, "%s: UNICODE_STRING is not valid UTF-8", k->key);
		if (!(*data = malloc((size_t)m)))
			return -ENOMEM;
		json_od_utf8_to_utf16le(s, *data, (uint32_t)m);
		*size = (uint32_t)m;
		return 0;
	case CO_T_OCTET_STRING:
	case CO_T_DOMAIN:
		return encode_hex(c, k, t, data, size);
	default:
		return fail(c, k->line, "%s: values of %s are not supported in EDS/DCF files",
			    k->key, co_type_to_string(t));
	}
}

/* A LowLimit/HighLimit key, or NULL when it is absent, empty or (read
 * leniently) not a number of the type: then it is not checked. */
static const ini_key *limit_key(eds_ctx *c, const var_spec *v, co_type t, const char *name,
				uint64_t *bits, int *rc)
{
	const ini_key *k = get_key(v->sec, name);

	*rc = 0;
	if (!k || !*k->val)
		return NULL;
	*rc = parse_num(c, k, t, bits);
	if (*rc) {
		*rc = tolerate_failure(c, *rc, "the limit is not checked");
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
	if (lo && hi && num_cmp(t, lb, hb) > 0) {
		if (c->strict)
			return fail(c, hi->line, "HighLimit '%s' is below LowLimit '%s' (line %u)",
				    hi->val, lo->val, lo->line);
		warn(c, hi->line,
		     "HighLimit '%s' is below LowLimit '%s' (line %u): the limits are not checked",
		     hi->val, lo->val, lo->line);
		return 0;
	}
	if (lo && num_cmp(t, bits, lb) < 0)
		return fail(c, v->value->line, "%s '%s' is below LowLimit '%s' (line %u)",
			    v->value->key, v->value->val, lo->val, lo->line);
	if (hi && num_cmp(t, bits, hb) > 0)
		return fail(c, v->value->line, "%s '%s' is above HighLimit '%s' (line %u)",
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
	if ((rc = parse_num(c, v->value, t, &bits)) || (rc = limit_check(c, v, t, bits)))
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

static int do_var(eds_ctx *c, const var_spec *v, co_type t, uint8_t access)
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
	    !(rc = tolerate_failure(c, rc, "the value is not used"))) {
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
	return add_var(c, v->index, v->sub, v->value->line, data, size);
}

static const ini_key *value_key(const ini_sec *s)
{
	const ini_key *k = get_key(s, "ParameterValue");
	if (!k || !*k->val)
		k = get_key(s, "DefaultValue");
	return k && *k->val ? k : NULL;
}

static bool has_parameter_value(const ini_sec *s)
{
	const ini_key *k = s ? get_key(s, "ParameterValue") : NULL;
	return k && *k->val;
}

/* An entry whose DataType or AccessType cannot be used (rc, reason in
 * c->msg): refused when it carries a configured value, else left out
 * with a warning - python-canopen, too, writes nothing of an entry of
 * an unknown type. */
static int tolerate_untyped(eds_ctx *c, bool configured, int rc)
{
	return configured ? rc : tolerate_failure(c, rc, "the entry is not used");
}

/* A VAR-like section (an object of type VAR/DOMAIN, or a sub-object). */
static int do_plain(eds_ctx *c, const ini_sec *s, uint16_t index, uint8_t sub, bool is_domain)
{
	const ini_key *ak = get_key(s, "AccessType");
	var_spec v = {
		.index = index, .sub = sub, .sec = s, .value = value_key(s), .where = s->name
	};
	co_type t = CO_T_DOMAIN;
	uint8_t access = 0;
	int rc = 0;

	if (!(is_domain && !get_key(s, "DataType")))
		rc = parse_type(c, s, &t);
	if (!rc && !ak)
		rc = fail(c, s->line, "[%s]: AccessType missing", s->name);
	else if (!rc)
		rc = parse_access(c, ak, &access);
	if (rc)
		return tolerate_untyped(c, has_parameter_value(s), rc);
	return do_var(c, &v, t, access);
}

/* [XXXXObjectLinks] and the object lists: a count key, then 1..count.
 * Read leniently, a missing count and entries that do not fit it are
 * warnings (they only describe, nothing is lost). */
static int check_keyed_list(eds_ctx *c, const ini_sec *s, const char *count_key, uint64_t max,
			    const ini_key **count_k)
{
	const ini_key *k = get_key(s, count_key);
	uint64_t count = 0;
	int rc;

	*count_k = k;
	if (!k)
		return tolerate(c, s->line, "[%s]: %s missing", s->name, count_key);
	if ((rc = parse_uint_key(c, k, max, &count)))
		return tolerate_failure(c, rc, "the count is not checked");
	for (size_t i = 0; i < s->nkeys; i++) {
		const ini_key *e = &s->keys[i];
		char *end;
		unsigned long n;
		if (e == k)
			continue;
		errno = 0;
		n = strtoul(e->key, &end, 10);
		if (*end || end == e->key || errno || e->key[0] == '-' || e->key[0] == '+')
			rc = tolerate(c, e->line, "[%s]: unexpected key '%s'", s->name, e->key);
		else if ((n < 1 || n > count) && count == s->nkeys - 1) /* else: the count */
			rc = tolerate(c, e->line, "[%s]: entry %s beyond %s=%llu", s->name, e->key,
				      count_key, (unsigned long long)count);
		if (rc)
			return rc;
	}
	if (count != s->nkeys - 1)
		return tolerate(c, k->line, "[%s]: %s=%llu but %zu entries", s->name, count_key,
				(unsigned long long)count, s->nkeys - 1);
	return 0;
}

/* Each numbered entry of a list names an object (its index); one the
 * file does not describe is a warning. */
static int check_listed_objects(eds_ctx *c, const ini_sec *s, const ini_key *count_k)
{
	for (size_t i = 0; i < s->nkeys; i++) {
		const ini_key *k = &s->keys[i];
		uint64_t idx;
		char *end;
		int rc;
		if (k == count_k)
			continue;
		(void)strtoul(k->key, &end, 10);
		if (*end || end == k->key)
			continue; /* reported by check_keyed_list */
		if ((rc = parse_uint_key(c, k, 0xFFFF, &idx))) {
			if ((rc = tolerate_failure(c, rc, "the entry is ignored")))
				return rc;
			continue;
		}
		if (find_sec(c, SEC_OBJ, (uint16_t)idx, 0, NULL))
			continue;
		if (s->kind == SEC_LINKS)
			rc = tolerate(c, k->line, "[%s]: linked object 0x%04llX has no section",
				      s->name, (unsigned long long)idx);
		else
			rc = tolerate(c, k->line,
				      "[%s]: object 0x%04llX listed but no section [%04llX]",
				      s->name, (unsigned long long)idx, (unsigned long long)idx);
		if (rc)
			return rc;
	}
	return 0;
}

/* [XXXXName] and [XXXXValue] of a compact object: NrOfEntries=k, then k
 * keys "sub=..." with sub-indexes 1..n (decimal). Read leniently, a wrong
 * count and names that fit no sub-object are warnings; a configured value
 * for a sub-object the object does not have is refused. */
static int check_compact_list(eds_ctx *c, const ini_sec *s, uint64_t n, bool values)
{
	const ini_key *k = get_key(s, "NrOfEntries");
	uint64_t cnt = 0;
	int rc;

	if (!k && (rc = tolerate(c, s->line, "[%s]: NrOfEntries missing", s->name)))
		return rc;
	if (k && (rc = parse_uint_key(c, k, 255, &cnt)) &&
	    (rc = tolerate_failure(c, rc, "the count is not checked")))
		return rc;
	for (size_t i = 0; i < s->nkeys; i++) {
		const ini_key *e = &s->keys[i];
		char *end;
		unsigned long sub;
		if (e == k)
			continue;
		errno = 0;
		sub = strtoul(e->key, &end, 10);
		if (*end || end == e->key || errno || e->key[0] == '-' || e->key[0] == '+') {
			if ((rc = tolerate(c, e->line, "[%s]: unexpected key '%s'%s", s->name,
					   e->key, c->strict ? "" : " (ignored)")))
				return rc;
			continue;
		}
		if (sub >= 1 && sub <= n)
			continue;
		if (values)
			return fail(c, e->line, "[%s]: sub-index %s beyond CompactSubObj=%llu",
				    s->name, e->key, (unsigned long long)n);
		if ((rc = tolerate(c, e->line, "[%s]: sub-index %s beyond CompactSubObj=%llu%s",
				   s->name, e->key, (unsigned long long)n,
				   c->strict ? "" : " (ignored)")))
			return rc;
	}
	if (k && cnt != s->nkeys - 1)
		return tolerate(c, k->line, "[%s]: NrOfEntries=%llu but %zu entries", s->name,
				(unsigned long long)cnt, s->nkeys - 1);
	return 0;
}

/* The value of sub-index `sub` in a [XXXXValue] section. */
static const ini_key *compact_value(const ini_sec *vals, unsigned sub)
{
	char key[8];
	if (!vals)
		return NULL;
	snprintf(key, sizeof(key), "%u", sub);
	const ini_key *k = get_key(vals, key);
	return k && *k->val ? k : NULL;
}

static int do_compact(eds_ctx *c, const ini_sec *o, const ini_key *ck)
{
	const ini_sec *names = find_sec(c, SEC_NAME, o->index, 0, NULL);
	const ini_sec *vals = find_sec(c, SEC_VALUE, o->index, 0, NULL);
	const ini_key *ak = get_key(o, "AccessType");
	uint64_t n;
	co_type t;
	uint8_t access = 0;
	int rc;

	if ((rc = parse_uint_key(c, ck, 255, &n)))
		return rc;
	if (n == 0 && c->strict)
		return fail(c, ck->line, "CompactSubObj must be 1..254");
	if (n == 0) {
		warn(c, ck->line, "[%s]: CompactSubObj=0: no sub-objects", o->name);
		return 0;
	}
	/* python-canopen makes sub-objects 1..255 of it; sub-index FFh is
	 * the object's structure (CiA 301), not an element */
	if (n == 255 &&
	    (rc = tolerate(c, ck->line,
			   "[%s]: CompactSubObj=255, but sub-index FFh is reserved (CiA 301)%s",
			   o->name, c->strict ? "" : ": sub-objects 1..254 are used")))
		return rc;
	if (n == 255)
		n = 254;
	rc = parse_type(c, o, &t);
	if (!rc && !ak)
		rc = fail(c, o->line, "[%s]: AccessType missing", o->name);
	else if (!rc)
		rc = parse_access(c, ak, &access);
	if (rc)
		return tolerate_untyped(c, has_parameter_value(o) || (vals && vals->nkeys > 1), rc);
	if (find_sec(c, SEC_SUB, o->index, 0, NULL) ||
	    lower_bound(c, SEC_SUB, o->index) < lower_bound(c, SEC_NAME, o->index))
		return fail(c, o->line, "[%s]: CompactSubObj and sub-object sections together",
			    o->name);
	if (names && (rc = check_compact_list(c, names, n, false)))
		return rc;
	if (vals && (rc = check_compact_list(c, vals, n, true)))
		return rc;
	/* sub0 = n, UNSIGNED8 read-only: nothing to write */
	for (unsigned s = 1; s <= n; s++) {
		var_spec v = { .index = o->index, .sub = (uint8_t)s, .sec = o, .where = o->name };
		v.value = compact_value(vals, s);
		if (!v.value)
			v.value = value_key(o);
		if ((rc = do_var(c, &v, t, access)))
			return rc;
	}
	return 0;
}

static const char *object_type_name(uint64_t ot)
{
	return ot == CO_OBJ_VAR      ? "VAR"
	       : ot == CO_OBJ_DOMAIN ? "DOMAIN"
	       : ot == CO_OBJ_ARRAY  ? "ARRAY"
				     : "RECORD";
}

/* A VAR or DOMAIN object: sub-object sections, SubNumber and
 * CompactSubObj do not belong to it; python-canopen ignores them. */
static int do_var_object(eds_ctx *c, const ini_sec *o, uint64_t ot, const ini_key *sn,
			 const ini_key *ck, size_t first, size_t last)
{
	int rc;

	if (first < last &&
	    (rc = tolerate(c, c->sorted[first]->line, "[%s]: sub-object of %s object [%s]%s",
			   c->sorted[first]->name, object_type_name(ot), o->name,
			   c->strict ? "" : " (ignored)")))
		return rc;
	if ((sn || ck) && (rc = tolerate(c, (sn ? sn : ck)->line, "[%s]: %s on a %s object%s",
					 o->name, (sn ? sn : ck)->key, object_type_name(ot),
					 c->strict ? "" : " (ignored)")))
		return rc;
	return do_plain(c, o, o->index, 0, ot == CO_OBJ_DOMAIN);
}

/* ARRAY/RECORD with sub-object sections. SubNumber (CiA 306: the number
 * of sub-objects) that disagrees with the sections is a warning: the
 * sections present are what python-canopen and the CANopenNode editor
 * read, and so do we. */
static int do_sub_sections(eds_ctx *c, const ini_sec *o, uint64_t ot, const ini_key *sn,
			   size_t first, size_t last)
{
	uint64_t n = 0;
	int rc;

	if (!sn && (rc = tolerate(c, o->line, "[%s]: %s without SubNumber or CompactSubObj",
				  o->name, object_type_name(ot))))
		return rc;
	if (sn && (rc = parse_uint_key(c, sn, 255, &n)) &&
	    (rc = tolerate_failure(c, rc, "the sub-object sections present are used")))
		return rc;
	if (sn && !rc && n == 0 &&
	    (rc = tolerate(c, sn->line, "[%s]: SubNumber 0 (an %s has at least sub-index 0)",
			   o->name, object_type_name(ot))))
		return rc;
	if (sn && n && last - first != n &&
	    (rc = tolerate(c, sn->line,
			   "[%s]: SubNumber=%llu but %zu sub-object sections [%04XsubN]%s", o->name,
			   (unsigned long long)n, last - first, o->index,
			   c->strict ? "" : ": the sections present are used")))
		return rc;
	if (first < last && c->sorted[first]->sub != 0 &&
	    (rc = tolerate(c, o->line, "[%s]: no sub-object section [%04Xsub0]", o->name,
			   o->index)))
		return rc;
	for (size_t i = first; i < last; i++) {
		const ini_sec *s = c->sorted[i];
		const ini_key *sot = get_key(s, "ObjectType");
		uint64_t so = CO_OBJ_VAR;
		if (sot && *sot->val && (rc = parse_uint_key(c, sot, 0xFF, &so)) &&
		    (rc = tolerate_failure(c, rc, "taken as 0x7 (VAR)")))
			return rc;
		if (so != CO_OBJ_VAR &&
		    (rc = tolerate(c, sot->line,
				   "[%s]: a sub-object must have ObjectType 0x7 (VAR)%s", s->name,
				   c->strict ? "" : "; taken as VAR")))
			return rc;
		if ((rc = do_plain(c, s, s->index, s->sub, false)))
			return rc;
	}
	return 0;
}

static int do_object(eds_ctx *c, const ini_sec *o)
{
	const ini_key *otk = get_key(o, "ObjectType");
	const ini_key *sn = get_key(o, "SubNumber"), *ck = get_key(o, "CompactSubObj");
	uint64_t ot = CO_OBJ_VAR;
	size_t first = lower_bound(c, SEC_SUB, o->index), last = lower_bound(c, SEC_NAME, o->index);
	int rc;

	c->st.objects++;
	if (o->index == 0)
		return fail(c, o->line, "[%s]: index 0000h is not an object", o->name);
	if (otk && !*otk->val && !c->strict)
		otk = NULL; /* CiA 306: no ObjectType is VAR */
	if (otk && (rc = parse_uint_key(c, otk, 0xFF, &ot)))
		return rc;
	if (ck && !*ck->val)
		ck = NULL;
	if (sn && !*sn->val && !c->strict)
		sn = NULL;
	switch (ot) {
	case CO_OBJ_DEFTYPE:
	case CO_OBJ_DEFSTRUCT:
		return 0; /* type definitions: nothing to configure */
	case CO_OBJ_VAR:
	case CO_OBJ_DOMAIN:
		return do_var_object(c, o, ot, sn, ck, first, last);
	case CO_OBJ_ARRAY:
	case CO_OBJ_RECORD:
		break;
	default: /* python-canopen skips such an object, and so do we */
		return tolerate(c, otk->line,
				"ObjectType '%s' is not one of 0x2 (DOMAIN), 0x5 (DEFTYPE), 0x6 "
				"(DEFSTRUCT), 0x7 (VAR), 0x8 (ARRAY), 0x9 (RECORD)%s",
				otk->val, c->strict ? "" : ": the object is not used");
	}
	if (ck && ot != CO_OBJ_ARRAY && find_sec(c, SEC_VALUE, o->index, 0, NULL))
		return fail(c, ck->line, "[%s]: CompactSubObj on a RECORD (only ARRAY)", o->name);
	if (ck && ot != CO_OBJ_ARRAY &&
	    (rc = tolerate(c, ck->line, "[%s]: CompactSubObj on a RECORD (only ARRAY)%s", o->name,
			   c->strict ? "" : ": the sub-object sections are used")))
		return rc;
	if (ck && ot == CO_OBJ_ARRAY) {
		if (sn) {
			uint64_t n;
			if ((rc = parse_uint_key(c, sn, 255, &n)))
				return rc;
			if (n != 0)
				return fail(c, sn->line,
					    "[%s]: SubNumber and CompactSubObj together", o->name);
		}
		return do_compact(c, o, ck);
	}
	return do_sub_sections(c, o, ot, sn, first, last);
}

/* [XXXXObjectLinks]: ObjectLinks=n, 1..n = indexes of described objects. */
static int do_links(eds_ctx *c, const ini_sec *s)
{
	const ini_key *count_k;
	int rc;

	if (!find_sec(c, SEC_OBJ, s->index, 0, NULL))
		return 0; /* reported by check_orphans */
	if ((rc = check_keyed_list(c, s, "ObjectLinks", 0xFFFF, &count_k)))
		return rc;
	return check_listed_objects(c, s, count_k);
}

/* Strict reading refuses a malformed object list (no count, an entry
 * that is no index). */
static int check_list_strictly(eds_ctx *c, const ini_sec *s)
{
	const ini_key *sk = get_key(s, "SupportedObjects");
	uint64_t n;
	int rc;

	if (!sk)
		return fail(c, s->line, "[%s]: SupportedObjects missing", s->name);
	if ((rc = parse_uint_key(c, sk, 0xFFFF, &n)))
		return rc;
	for (size_t i = 0; i < s->nkeys; i++) {
		const ini_key *k = &s->keys[i];
		char *end;
		if (k == sk)
			continue;
		errno = 0;
		(void)strtoul(k->key, &end, 10);
		if (*end || end == k->key || errno || k->key[0] == '-' || k->key[0] == '+')
			return fail(c, k->line, "[%s]: unexpected key '%s'", s->name, k->key);
		if ((rc = parse_uint_key(c, k, 0xFFFF, &n)))
			return rc;
	}
	return 0;
}

/* [MandatoryObjects] etc.: SupportedObjects=n, 1..n = indexes. Vendor
 * files get the count wrong and list objects they do not describe;
 * nothing is lost, so these are warnings also when reading strictly. */
static int do_list(eds_ctx *c, const char *name)
{
	const ini_sec *s = find_sec(c, SEC_OTHER, 0, 0, name);
	const ini_key *count_k;
	bool strict = c->strict;
	int rc;

	if (!s)
		return 0;
	if (strict && (rc = check_list_strictly(c, s)))
		return rc;
	c->strict = false;
	rc = check_keyed_list(c, s, "SupportedObjects", 0xFFFF, &count_k);
	if (!rc)
		rc = check_listed_objects(c, s, count_k);
	c->strict = strict;
	return rc;
}

static int check_orphans(eds_ctx *c)
{
	for (size_t i = 0; i < c->nsecs; i++) {
		const ini_sec *s = c->sorted[i];
		const ini_sec *o;
		if (s->kind == SEC_OTHER || s->kind == SEC_OBJ)
			continue;
		int rc = 0;
		o = find_sec(c, SEC_OBJ, s->index, 0, NULL);
		/* a sub-object without its object has no object type, and
		 * configured values without their object have no type: both
		 * unusable (python-canopen refuses the first too) */
		if (!o && (s->kind == SEC_SUB || s->kind == SEC_VALUE))
			return fail(c, s->line, "[%s] without object [%04X]", s->name, s->index);
		if (!o)
			rc = tolerate(c, s->line, "[%s] without object [%04X]%s", s->name, s->index,
				      c->strict ? "" : " (ignored)");
		else if (s->kind == SEC_VALUE && !get_key(o, "CompactSubObj"))
			return fail(c, s->line, "[%s] but [%s] has no CompactSubObj", s->name,
				    o->name);
		else if (s->kind == SEC_NAME && !get_key(o, "CompactSubObj"))
			rc = tolerate(c, s->line, "[%s] but [%s] has no CompactSubObj%s", s->name,
				      o->name, c->strict ? "" : " (ignored)");
		if (rc)
			return rc;
	}
	return 0;
}

static int node_from_file(eds_ctx *c)
{
	const ini_sec *s = find_sec(c, SEC_OTHER, 0, 0, "DeviceComissioning");
	const ini_key *k = s ? get_key(s, "NodeID") : NULL;
	uint64_t id;
	int rc;

	if (!k || !*k->val)
		return 0;
	/* EDS files carry NodeID=0 for "not commissioned": read leniently,
	 * a NodeID that is no node id is not used */
	if ((rc = parse_uint_key(c, k, 127, &id)))
		return tolerate_failure(c, rc, "NodeID is not used");
	if (id < 1)
		return tolerate(c, k->line, "NodeID must be 1..127%s",
				c->strict ? "" : ": NodeID is not used");
	c->node_id = (uint8_t)id;
	return 0;
}

/* ---- emitting in download order ------------------------------------------------- */

static out_var *find_var(eds_ctx *c, uint16_t index, uint8_t sub)
{
	for (size_t i = 0; i < c->nvars; i++)
		if (c->vars[i].index == index && c->vars[i].sub == sub)
			return &c->vars[i];
	return NULL;
}

static int emit(eds_ctx *c, const out_var *v)
{
	if (grow((void **)&c->emit, &c->ecap, c->nemit + 1, sizeof(*c->emit)))
		return -ENOMEM;
	c->emit[c->nemit++] = *v;
	return 0;
}

static uint32_t u32_of(const out_var *v)
{
	uint32_t x = 0;
	for (uint32_t i = 0; i < v->size && i < 4; i++)
		x |= (uint32_t)v->data[i] << (8 * i);
	return x;
}

static bool is_pdo_comm(uint16_t i)
{
	return (i >= 0x1400 && i <= 0x15FF) || (i >= 0x1800 && i <= 0x19FF);
}

static bool is_pdo_map(uint16_t i)
{
	return (i >= 0x1600 && i <= 0x17FF) || (i >= 0x1A00 && i <= 0x1BFF);
}

/* Constant bytes for the re-mapping steps live in the context's vars. */
static int emit_const(eds_ctx *c, uint16_t index, uint8_t sub, uint32_t val, uint32_t size,
		      unsigned line)
{
	uint8_t *d = malloc(4);
	out_var v;
	int rc;

	if (!d)
		return -ENOMEM;
	for (int i = 0; i < 4; i++)
		d[i] = (uint8_t)(val >> (8 * i));
	v = (out_var){ .index = index, .sub = sub, .line = line, .data = d, .size = size };
	if ((rc = add_var(c, index, sub, line, d, size)))
		return rc;
	return emit(c, &v);
}

static int emit_pdo(eds_ctx *c, uint16_t comm, uint16_t map, size_t nvars)
{
	const out_var *cob = find_var(c, comm, 1), *m0 = find_var(c, map, 0);
	uint32_t cob_val = cob ? u32_of(cob) : 0;
	int rc;

	/* The re-mapping steps rewrite these two: they must have the sizes
	 * CiA 301 gives them (found by fuzzing: a string COB-ID was read past
	 * the 4 bytes of its "disabled" copy). */
	if (cob && cob->size != 4)
		return fail(c, cob->line, "PDO %04Xh sub 1 (COB-ID): %u bytes, UNSIGNED32 has 4",
			    comm, (unsigned)cob->size);
	if (m0 && m0->size != 1)
		return fail(
			c, m0->line,
			"PDO mapping %04Xh sub 0 (number of entries): %u bytes, UNSIGNED8 has 1",
			map, (unsigned)m0->size);
	if (cob && (rc = emit_const(c, comm, 1, cob_val | 0x80000000u, cob->size, cob->line)))
		return rc;
	cob = find_var(c, comm, 1); /* add_var may have moved the array */
	m0 = find_var(c, map, 0);
	for (size_t i = 0; i < nvars; i++)
		if (c->vars[i].index == comm && c->vars[i].sub != 1 && (rc = emit(c, &c->vars[i])))
			return rc;
	if (m0) {
		uint8_t n = m0->data[0];
		unsigned line = m0->line;
		if (n > 0x40)
			return fail(c, line, "PDO mapping %04Xh: sub0=%u, at most 64 entries", map,
				    n);
		if ((rc = emit_const(c, map, 0, 0, 1, line)))
			return rc;
		for (unsigned s = 1; s <= n; s++) {
			const out_var *e = find_var(c, map, (uint8_t)s);
			if (!e)
				return fail(c, line,
					    "PDO mapping %04Xh: sub0=%u but sub %u has no writable "
					    "value",
					    map, n, s);
			if ((rc = emit(c, e)))
				return rc;
		}
		m0 = find_var(c, map, 0);
		if (n && (rc = emit(c, m0)))
			return rc;
	} else {
		for (size_t i = 0; i < nvars; i++)
			if (c->vars[i].index == map && (rc = emit(c, &c->vars[i])))
				return rc;
	}
	cob = find_var(c, comm, 1);
	if (cob && !(cob_val & 0x80000000u) && (rc = emit(c, cob)))
		return rc;
	return 0;
}

static int order_vars(eds_ctx *c)
{
	size_t nvars = c->nvars; /* emit_const appends; walk the original ones */
	int rc;

	for (size_t i = 0; i < nvars; i++) {
		uint16_t idx = c->vars[i].index;
		if (i > 0 && c->vars[i - 1].index == idx)
			continue; /* one group per index */
		if (is_pdo_comm(idx)) {
			rc = emit_pdo(c, idx, (uint16_t)(idx + 0x200), nvars);
		} else if (is_pdo_map(idx)) {
			bool comm_written = false;
			for (size_t j = 0; j < nvars; j++)
				comm_written |= c->vars[j].index == idx - 0x200;
			rc = comm_written ? 0 : emit_pdo(c, (uint16_t)(idx - 0x200), idx, nvars);
		} else {
			rc = 0;
			for (size_t j = i; j < nvars && c->vars[j].index == idx && !rc; j++)
				rc = emit(c, &c->vars[j]);
		}
		if (rc)
			return rc;
	}
	return 0;
}

static int write_cdcf(eds_ctx *c, uint8_t **out, size_t *out_len)
{
	co_cdcf_writer w;
	long n;
	uint8_t *buf;

	co_cdcf_writer_init(&w, NULL, 0);
	for (size_t i = 0; i < c->nemit; i++)
		co_cdcf_writer_add(&w, c->emit[i].index, c->emit[i].sub, c->emit[i].data,
				   c->emit[i].size);
	n = co_cdcf_writer_finish(&w);
	if (n < 0)
		return fail(c, 0, "cannot build the concise DCF (%s)", strerror((int)-n));
	buf = malloc((size_t)n);
	if (!buf)
		return -ENOMEM;
	co_cdcf_writer_init(&w, buf, (size_t)n);
	for (size_t i = 0; i < c->nemit; i++)
		co_cdcf_writer_add(&w, c->emit[i].index, c->emit[i].sub, c->emit[i].data,
				   c->emit[i].size);
	if (co_cdcf_writer_finish(&w) != n) {
		free(buf);
		return fail(c, 0, "concise DCF writer disagrees with itself");
	}
	*out = buf;
	*out_len = (size_t)n;
	c->st.entries = (unsigned)c->nemit;
	return 0;
}

static void ctx_free(eds_ctx *c)
{
	for (size_t i = 0; i < c->nsecs; i++)
		free(c->secs[i].keys);
	for (size_t i = 0; i < c->nvars; i++)
		free(c->vars[i].data);
	free(c->secs);
	free(c->sorted);
	free(c->vars);
	free(c->emit);
	free(c->text);
}

static int convert(eds_ctx *c, const char *text, size_t len, uint8_t **out, size_t *out_len)
{
	int rc;

	if (c->node_id > 127)
		return fail(c, 0, "node id %u is out of range 1..127", c->node_id);
	if (len > EDS_FILE_MAX)
		return fail(c, 0, "file larger than %u bytes", EDS_FILE_MAX);
	c->text = malloc(len + 1);
	if (!c->text)
		return -ENOMEM;
	memcpy(c->text, text, len);
	c->text[len] = '\0';

	if ((rc = parse_ini(c, len)) || (rc = sort_sections(c)))
		return rc;
	if (!c->node_id && (rc = node_from_file(c)))
		return rc;
	if ((rc = do_list(c, "MandatoryObjects")) || (rc = do_list(c, "OptionalObjects")) ||
	    (rc = do_list(c, "ManufacturerObjects")) || (rc = check_orphans(c)))
		return rc;
	for (size_t i = 0; i < c->nsecs && !rc; i++) {
		if (c->sorted[i]->kind == SEC_OBJ)
			rc = do_object(c, c->sorted[i]);
		else if (c->sorted[i]->kind == SEC_LINKS)
			rc = do_links(c, c->sorted[i]);
	}
	if (!rc && !c->st.objects)
		rc = fail(c, 0, "no object sections: not an EDS or DCF");
	if (rc || (rc = order_vars(c)) || (rc = write_cdcf(c, out, out_len)))
		return rc;
	c->st.node_id = c->node_id;
	return 0;
}

int eds_convert_opts(const char *text, size_t len, const char *file, const eds_options *opts,
		     uint8_t **out, size_t *out_len, eds_stats *stats, char *err, size_t errlen)
{
	eds_ctx c = { .file = file ? file : "(buffer)",
		      .node_id = opts->node_id,
		      .strict = opts->strict,
		      .on_warning = opts->on_warning,
		      .warning_arg = opts->warning_arg,
		      .on_entry = opts->on_entry,
		      .entry_arg = opts->entry_arg };
	int rc;

	*out = NULL;
	*out_len = 0;
	rc = convert(&c, text, len, out, out_len);
	if (rc) {
		free(*out);
		*out = NULL;
		*out_len = 0;
	}
	if (stats)
		*stats = c.st; /* warnings too when the file was refused */
	if (err && errlen) {
		if (rc == -ENOMEM)
			snprintf(err, errlen, "%s: out of memory", c.file);
		else
			snprintf(err, errlen, "%s", rc ? c.msg : "");
	}
	ctx_free(&c);
	return rc;
}

int eds_convert(const char *text, size_t len, const char *file, uint8_t node_id, uint8_t **out,
		size_t *out_len, eds_stats *stats, char *err, size_t errlen)
{
	eds_options o = { .node_id = node_id };

	return eds_convert_opts(text, len, file, &o, out, out_len, stats, err, errlen);
}

int eds_convert_file_opts(const char *path, const eds_options *opts, uint8_t **out, size_t *out_len,
			  eds_stats *stats, char *err, size_t errlen)
{
	uint8_t *buf;
	size_t len;
	int rc;

	*out = NULL;
	*out_len = 0;
	if ((rc = cogw_file_read(path, EDS_FILE_MAX, &buf, &len, err, errlen)))
		return rc;
	rc = eds_convert_opts((const char *)buf, len, path, opts, out, out_len, stats, err, errlen);
	free(buf);
	return rc;
}

int eds_convert_file(const char *path, uint8_t node_id, uint8_t **out, size_t *out_len,
		     eds_stats *stats, char *err, size_t errlen)
{
	eds_options o = { .node_id = node_id };

	return eds_convert_file_opts(path, &o, out, out_len, stats, err, errlen);
}
