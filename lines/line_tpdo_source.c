/* SPDX-License-Identifier: MIT */
/*
 * lines/line_tpdo_source.c - the objects a TPDO's frame carries when an
 * extension builds the frame itself (line_ext.h): one extension names
 * them, another builds the same frame from them. Line thread only.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <string.h>

static struct line_tpdo_sources *find(line *l, uint16_t nr)
{
	for (unsigned i = 0; i < LINE_TPDO_SOURCES_MAX; i++)
		if (l->tpdo_sources[i].nr == nr)
			return &l->tpdo_sources[i];
	return NULL;
}

static bool same(const struct line_tpdo_sources *t, const line_tpdo_source *src, uint8_t n)
{
	if (t->n != n)
		return false;
	for (uint8_t i = 0; i < n; i++)
		if (t->src[i].index != src[i].index || t->src[i].sub != src[i].sub ||
		    t->src[i].bits != src[i].bits || t->src[i].is_signed != src[i].is_signed)
			return false;
	return true;
}

int line_tpdo_sources_set(line *l, uint16_t nr, const line_tpdo_source *src, uint8_t n)
{
	struct line_tpdo_sources *t = find(l, nr);

	if (nr == 0 || n > LINE_TPDO_SOURCE_ENTRIES)
		return -EINVAL;
	if (n == 0) {
		if (t) {
			memset(t, 0, sizeof *t);
			l->tpdo_sources_gen++;
		}
		return 0;
	}
	for (uint8_t i = 0; i < n; i++)
		if (src[i].bits == 0 || src[i].bits > 64)
			return -EINVAL;
	if (t && same(t, src, n))
		return 0;
	if (!t && !(t = find(l, 0)))
		return -ENOSPC;
	memset(t, 0, sizeof *t);
	t->nr = nr;
	t->n = n;
	memcpy(t->src, src, n * sizeof *src);
	l->tpdo_sources_gen++;
	return 0;
}

uint8_t line_tpdo_sources_get(const line *l, uint16_t nr, const line_tpdo_source **src)
{
	struct line_tpdo_sources *t = nr ? find((line *)l, nr) : NULL;

	*src = t ? t->src : NULL;
	return t ? t->n : 0;
}

uint32_t line_tpdo_sources_generation(const line *l)
{
	return l->tpdo_sources_gen;
}
