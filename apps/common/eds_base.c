/* SPDX-License-Identifier: MIT */
/*
 * apps/common/eds_base.c - what every pass of the EDS/DCF reader uses: the
 * refusal, the warning and the tolerated inconsistency (a warning, or a
 * refusal when reading strictly), growing arrays, trimming, hex digits.
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

/* "file:line: " and the reason into buf. */
static void vformat(const eds_ctx *c, char *buf, size_t size, unsigned line, const char *fmt,
		    va_list ap)
{
	int n = snprintf(buf, size, "%s:%u: ", c->file, line);

	if (n >= 0 && (size_t)n < size)
		vsnprintf(buf + n, size - (size_t)n, fmt, ap);
}

int eds_fail(eds_ctx *c, unsigned line, const char *fmt, ...)
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

void eds_warn(eds_ctx *c, unsigned line, const char *fmt, ...)
{
	va_list ap;

	va_start(ap, fmt);
	vwarn(c, line, fmt, ap);
	va_end(ap);
}

/* Inconsistent but usable: a warning, or a refusal when reading strictly. */
int eds_tolerate(eds_ctx *c, unsigned line, const char *fmt, ...)
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
int eds_tolerate_failure(eds_ctx *c, int rc, const char *left_out)
{
	char text[sizeof(c->msg) + 80];

	if (rc != -EINVAL || c->strict || c->node_id_missing)
		return rc;
	snprintf(text, sizeof(text), "%s: %s", c->msg, left_out);
	c->msg[0] = '\0';
	warn_text(c, text);
	return 0;
}

int eds_grow(void **p, size_t *cap, size_t need, size_t elem)
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

/* s..end without the blanks around it, terminated. */
char *eds_trim(char *s, char *end)
{
	while (s < end && (*s == ' ' || *s == '\t'))
		s++;
	while (end > s && (end[-1] == ' ' || end[-1] == '\t' || end[-1] == '\r'))
		end--;
	*end = '\0';
	return s;
}

/* A hex digit's value, -1 for anything else. */
int eds_hexval(int ch)
{
	if (ch >= '0' && ch <= '9')
		return ch - '0';
	if (ch >= 'a' && ch <= 'f')
		return ch - 'a' + 10;
	if (ch >= 'A' && ch <= 'F')
		return ch - 'A' + 10;
	return -1;
}
