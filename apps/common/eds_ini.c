/* SPDX-License-Identifier: MIT */
/*
 * apps/common/eds_ini.c - passes 1 and 2 of the EDS/DCF reader: the INI text
 * to sections and keys, every line numbered, then the sections sorted so
 * that duplicates sit side by side and every lookup is a binary search.
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

/* ---- pass 1: INI text ------------------------------------------------------ */

static void classify(ini_sec *s)
{
	const char *n = s->name;
	unsigned v = 0;

	s->kind = SEC_OTHER;
	for (int i = 0; i < 4; i++) {
		int h = eds_hexval((unsigned char)n[i]);
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
			int h = eds_hexval((unsigned char)d[i]);
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
			eds_trim(s, p);
			return;
		}
}

/* "[name]" at s (trimmed, not empty) on line `line`: a new section. */
static int section_line(eds_ctx *c, char *s, unsigned line, ini_sec **cur)
{
	size_t n = strlen(s);
	char *name;

	if (s[n - 1] != ']' && !c->strict) {
		cut_inline_comment(s);
		n = strlen(s);
	}
	if (s[n - 1] != ']')
		return eds_fail(c, line, "section header without closing ']'");
	name = eds_trim(s + 1, s + n - 1);
	if (!*name)
		return eds_fail(c, line, "empty section name");
	if (eds_grow((void **)&c->secs, &c->cap, c->nsecs + 1, sizeof(*c->secs)))
		return -ENOMEM;
	*cur = &c->secs[c->nsecs++];
	memset(*cur, 0, sizeof(**cur));
	(*cur)->name = name;
	(*cur)->line = line;
	classify(*cur);
	if ((*cur)->kind == SEC_OTHER && strlen(name) > 4 &&
	    eds_hexval((unsigned char)name[0]) >= 0 && eds_hexval((unsigned char)name[1]) >= 0 &&
	    eds_hexval((unsigned char)name[2]) >= 0 && eds_hexval((unsigned char)name[3]) >= 0 &&
	    !strncasecmp(name + 4, "sub", 3))
		return eds_fail(c, line, "[%s]: sub-index must be 1 or 2 hex digits (00..FF)",
				name);
	return 0;
}

/* "key=value" at s (trimmed, not empty) on line `line`, into cur. */
static int key_line(eds_ctx *c, char *s, unsigned line, ini_sec *cur)
{
	char *eq = strchr(s, '=');
	if (!eq)
		return eds_fail(c, line, "expected [section] or key=value, got '%.40s'", s);
	if (!cur)
		return eds_fail(c, line, "key=value before the first [section]");
	char *key = eds_trim(s, eq);
	char *val = eds_trim(eq + 1, eq + 1 + strlen(eq + 1));
	if (!c->strict)
		cut_inline_comment(val);
	if (!*key)
		return eds_fail(c, line, "no key before '='");
	for (size_t i = 0; i < cur->nkeys; i++)
		if (!strcasecmp(cur->keys[i].key, key))
			return eds_fail(c, line, "duplicate key '%s' in [%s] (first at line %u)",
					key, cur->name, cur->keys[i].line);
	if (eds_grow((void **)&cur->keys, &cur->cap, cur->nkeys + 1, sizeof(*cur->keys)))
		return -ENOMEM;
	cur->keys[cur->nkeys++] = (ini_key){ .key = key, .val = val, .line = line };
	return 0;
}

int eds_parse_ini(eds_ctx *c, size_t len)
{
	char *p = c->text, *end = c->text + len;
	ini_sec *cur = NULL;
	unsigned line = 0;
	int rc;

	/* a UTF-8 byte order mark, as Windows editors write it */
	if (!c->strict && len >= 3 && !memcmp(p, "\xEF\xBB\xBF", 3))
		p += 3;
	while (p < end) {
		char *nl = memchr(p, '\n', (size_t)(end - p));
		char *le = nl ? nl : end;
		char *s;

		line++;
		if (memchr(p, '\0', (size_t)(le - p)))
			return eds_fail(c, line, "NUL byte: not a text file");
		s = eds_trim(p, le);
		p = nl ? nl + 1 : end;
		if (!*s || *s == ';' || *s == '#')
			continue;
		rc = *s == '[' ? section_line(c, s, line, &cur) : key_line(c, s, line, cur);
		if (rc)
			return rc;
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

int eds_sort_sections(eds_ctx *c)
{
	c->sorted = malloc((c->nsecs ? c->nsecs : 1) * sizeof(*c->sorted));
	if (!c->sorted)
		return -ENOMEM;
	for (size_t i = 0; i < c->nsecs; i++)
		c->sorted[i] = &c->secs[i];
	qsort(c->sorted, c->nsecs, sizeof(*c->sorted), sec_qcmp);
	for (size_t i = 1; i < c->nsecs; i++)
		if (!sec_cmp(c->sorted[i - 1], c->sorted[i]))
			return eds_fail(c, c->sorted[i]->line,
					"duplicate section [%s] (first at line %u)",
					c->sorted[i]->name, c->sorted[i - 1]->line);
	return 0;
}

ini_sec *eds_find_sec(const eds_ctx *c, enum sec_kind kind, uint16_t index, uint8_t sub,
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
size_t eds_lower_bound(const eds_ctx *c, enum sec_kind kind, uint16_t index)
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

const ini_key *eds_get_key(const ini_sec *s, const char *key)
{
	for (size_t i = 0; i < s->nkeys; i++)
		if (!strcasecmp(s->keys[i].key, key))
			return &s->keys[i];
	return NULL;
}
