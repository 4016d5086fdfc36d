/* SPDX-License-Identifier: MIT */
/*
 * apps/common/eds_emit.c - the collected values in the order a slave accepts
 * them (PDO parameters in the CiA 301 re-mapping order), written as a
 * concise DCF.
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
	if (eds_grow((void **)&c->emit, &c->ecap, c->nemit + 1, sizeof(*c->emit)))
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
	if ((rc = eds_add_var(c, index, sub, line, d, size)))
		return rc;
	return emit(c, &v);
}

/* A PDO's mapping in the CiA 301 re-mapping order: sub 0 = 0, the
 * entries, then sub 0 = n (without sub 0 the mapping's values as they
 * come). */
static int emit_mapping(eds_ctx *c, uint16_t map, size_t nvars)
{
	const out_var *m0 = find_var(c, map, 0);
	int rc;

	if (!m0) {
		for (size_t i = 0; i < nvars; i++)
			if (c->vars[i].index == map && (rc = emit(c, &c->vars[i])))
				return rc;
		return 0;
	}
	uint8_t n = m0->data[0];
	unsigned line = m0->line;
	if (n > 0x40)
		return eds_fail(c, line, "PDO mapping %04Xh: sub0=%u, at most 64 entries", map, n);
	if ((rc = emit_const(c, map, 0, 0, 1, line)))
		return rc;
	for (unsigned s = 1; s <= n; s++) {
		const out_var *e = find_var(c, map, (uint8_t)s);
		if (!e)
			return eds_fail(c, line,
					"PDO mapping %04Xh: sub0=%u but sub %u has no writable "
					"value",
					map, n, s);
		if ((rc = emit(c, e)))
			return rc;
	}
	m0 = find_var(c, map, 0);
	if (n && (rc = emit(c, m0)))
		return rc;
	return 0;
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
		return eds_fail(c, cob->line,
				"PDO %04Xh sub 1 (COB-ID): %u bytes, UNSIGNED32 has 4", comm,
				(unsigned)cob->size);
	if (m0 && m0->size != 1)
		return eds_fail(
			c, m0->line,
			"PDO mapping %04Xh sub 0 (number of entries): %u bytes, UNSIGNED8 has 1",
			map, (unsigned)m0->size);
	if (cob && (rc = emit_const(c, comm, 1, cob_val | 0x80000000u, cob->size, cob->line)))
		return rc;
	cob = find_var(c, comm, 1); /* add_var may have moved the array */
	for (size_t i = 0; i < nvars; i++)
		if (c->vars[i].index == comm && c->vars[i].sub != 1 && (rc = emit(c, &c->vars[i])))
			return rc;
	if ((rc = emit_mapping(c, map, nvars)))
		return rc;
	cob = find_var(c, comm, 1);
	if (cob && !(cob_val & 0x80000000u) && (rc = emit(c, cob)))
		return rc;
	return 0;
}

int eds_order_vars(eds_ctx *c)
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

int eds_write_cdcf(eds_ctx *c, uint8_t **out, size_t *out_len)
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
		return eds_fail(c, 0, "cannot build the concise DCF (%s)", strerror((int)-n));
	buf = malloc((size_t)n);
	if (!buf)
		return -ENOMEM;
	co_cdcf_writer_init(&w, buf, (size_t)n);
	for (size_t i = 0; i < c->nemit; i++)
		co_cdcf_writer_add(&w, c->emit[i].index, c->emit[i].sub, c->emit[i].data,
				   c->emit[i].size);
	if (co_cdcf_writer_finish(&w) != n) {
		free(buf);
		return eds_fail(c, 0, "concise DCF writer disagrees with itself");
	}
	*out = buf;
	*out_len = (size_t)n;
	c->st.entries = (unsigned)c->nemit;
	return 0;
}
