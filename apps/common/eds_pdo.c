/* SPDX-License-Identifier: MIT */
/*
 * apps/common/eds_pdo.c - the PDO layout and the type list of a device
 * file (the contract is in eds_pdo.h).
 *
 * A PDO is valid when its COB-ID (communication sub 1) has bit 31 clear
 * (CiA 301 §7.5.2.35/37); the mapping of an invalid one is not read, as the
 * device does not use it. PDO numbers with no communication record in the
 * file are not PDOs of the device; the walk goes over all 512 of each
 * direction, since files leave gaps (1800h, 1801h, 1803h).
 */
#include "apps/common/eds_pdo.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/od.h"
#include "core/pdo.h"

/* CiA 301 §7.4.7.1: the dummy entries of an RPDO name the data type
 * objects 0001h..0007h (BOOLEAN .. UNSIGNED32). */
#define DUMMY_INDEX_MAX 0x0007u

static int grow(eds_pdo_reader *r)
{
	size_t cap = r->cap ? r->cap * 2 : 256;
	co_pdo_layout_type *obj = realloc(r->obj, cap * sizeof *obj);
	if (!obj)
		return -ENOMEM;
	r->obj = obj;
	uint32_t *value = realloc(r->value, cap * sizeof *value);
	if (!value)
		return -ENOMEM;
	r->value = value;
	bool *has = realloc(r->has_value, cap * sizeof *has);
	if (!has)
		return -ENOMEM;
	r->has_value = has;
	r->cap = cap;
	return 0;
}

void eds_pdo_reader_on_entry(void *arg, const eds_entry *e)
{
	eds_pdo_reader *r = arg;
	uint32_t v = 0;

	if (r->out_of_memory)
		return;
	if (r->n == r->cap && grow(r)) {
		r->out_of_memory = true;
		return;
	}
	for (uint32_t i = 0; e->value && i < e->size && i < 4; i++)
		v |= (uint32_t)e->value[i] << (8 * i);
	r->obj[r->n] = (co_pdo_layout_type){
		.index = e->index, .sub = e->sub, .access = e->access, .type = e->type
	};
	r->value[r->n] = v;
	r->has_value[r->n] = e->value != NULL && e->size > 0;
	r->n++;
}

void eds_pdo_reader_free(eds_pdo_reader *r)
{
	if (!r)
		return;
	free(r->obj);
	free(r->value);
	free(r->has_value);
	memset(r, 0, sizeof *r);
}

void eds_pdo_file_free(eds_pdo_file *f)
{
	if (!f)
		return;
	free(f->pdo[CO_PDO_RX]);
	free(f->pdo[CO_PDO_TX]);
	memset(f, 0, sizeof *f);
}

static int type_cmp(const void *a, const void *b)
{
	const co_pdo_layout_type *x = a, *y = b;
	uint32_t kx = (uint32_t)x->index << 8 | x->sub, ky = (uint32_t)y->index << 8 | y->sub;
	return kx < ky ? -1 : kx > ky;
}

bool eds_pdo_types_sort(co_pdo_layout_type *list, size_t n, const co_pdo_layout_type **dup)
{
	if (n > 1)
		qsort(list, n, sizeof *list, type_cmp);
	for (size_t i = 1; i < n; i++)
		if (!type_cmp(&list[i - 1], &list[i])) {
			*dup = &list[i];
			return false;
		}
	return true;
}

/* The reader's record of index:sub (the first one), or -1. */
static long find(const eds_pdo_reader *r, uint16_t index, uint8_t sub)
{
	for (size_t i = 0; i < r->n; i++)
		if (r->obj[i].index == index && r->obj[i].sub == sub)
			return (long)i;
	return -1;
}

static bool value_of(const eds_pdo_reader *r, uint16_t index, uint8_t sub, uint32_t *v)
{
	long i = find(r, index, sub);
	if (i < 0 || !r->has_value[i])
		return false;
	*v = r->value[i];
	return true;
}

/* A file's layout being read: the reader's objects, their types, and
 * where a refusal goes. */
struct layout_read {
	const eds_pdo_reader *r;
	const char *file;
	const co_pdo_layout_type *types;
	size_t n_types;
	char *err;
	size_t errlen;
};

/* "file: TPDO nr (mapping map): why" into x->err, -EINVAL. */
static int fail(const struct layout_read *x, const co_pdo_layout_pdo *p, co_pdo_dir dir,
		const char *fmt, ...) __attribute__((format(printf, 4, 5)));

static int fail(const struct layout_read *x, const co_pdo_layout_pdo *p, co_pdo_dir dir,
		const char *fmt, ...)
{
	char why[200];
	va_list ap;
	uint16_t map = (uint16_t)((dir == CO_PDO_TX ? 0x1A00u : 0x1600u) + p->nr - 1u);

	va_start(ap, fmt);
	vsnprintf(why, sizeof why, fmt, ap);
	va_end(ap);
	snprintf(x->err, x->errlen, "%s: %s %u (mapping %04Xh): %s", x->file,
		 dir == CO_PDO_TX ? "TPDO" : "RPDO", p->nr, map, why);
	return -EINVAL;
}

/* The type and access of one mapped object: the configuration's override,
 * else the file's; the mapped length must be the type's (CiA 301 §7.4.7.1
 * maps whole objects; a BOOLEAN may take one bit). */
static int type_entry(co_pdo_layout_entry *e, co_pdo_dir dir, const co_pdo_layout_type *types,
		      size_t n_types, char *why, size_t whylen)
{
	if (dir == CO_PDO_RX && e->index >= 1 && e->index <= DUMMY_INDEX_MAX) {
		e->type = e->index;
		return 0;
	}
	const co_pdo_layout_type *t = co_pdo_layout_type_find(types, n_types, e->index, e->sub);
	if (!t)
		return 0;
	e->type = t->type;
	e->access = t->access;
	uint32_t size = co_type_size((co_type)t->type);
	bool fits = size == 0 || e->bits == size * 8u || (t->type == CO_T_BOOLEAN && e->bits == 1);
	if (!fits) {
		snprintf(why, whylen, "%04X:%02X is mapped with %u bits, but it is %s (%u bits)",
			 e->index, e->sub, e->bits, co_type_to_string((co_type)t->type),
			 (unsigned)size * 8u);
		return -EINVAL;
	}
	return 0;
}

/* One valid PDO of the file, n = 0..511 of direction dir. */
static int read_pdo(const struct layout_read *x, co_pdo_dir dir, unsigned n, uint32_t cob,
		    co_pdo_layout_pdo *p)
{
	const eds_pdo_reader *r = x->r;
	uint16_t comm = (uint16_t)((dir == CO_PDO_TX ? 0x1800u : 0x1400u) + n);
	uint16_t map = (uint16_t)(comm + 0x200u);
	uint32_t v = 0, count = 0, bits = 0;
	char why[160];

	memset(p, 0, sizeof *p);
	p->nr = (uint16_t)(n + 1);
	p->cob = cob;
	if (value_of(r, comm, 2, &v))
		p->tt = (uint8_t)v;
	if (value_of(r, comm, 3, &v))
		p->inhibit = (uint16_t)v;
	if (value_of(r, comm, 5, &v))
		p->event_ms = (uint16_t)v;
	if (value_of(r, comm, 6, &v))
		p->sync_start = (uint8_t)v;
	(void)value_of(r, map, 0, &count);
	if (count > CO_PDO_MAX_MAP)
		return fail(x, p, dir, "%u entries, at most %u", (unsigned)count, CO_PDO_MAX_MAP);
	for (unsigned i = 1; i <= count; i++) {
		co_pdo_layout_entry *e = &p->map[i - 1];
		if (!value_of(r, map, (uint8_t)i, &v))
			return fail(x, p, dir, "sub0 = %u but sub %u has no value", (unsigned)count,
				    i);
		e->index = (uint16_t)(v >> 16);
		e->sub = (uint8_t)(v >> 8);
		e->bits = (uint8_t)v;
		if (e->bits == 0)
			return fail(x, p, dir, "sub %u (%08Xh) maps 0 bits", i, (unsigned)v);
		bits += e->bits;
		if (bits > CO_PDO_MAX_BITS)
			return fail(x, p, dir, "the entries map more than %u bits",
				    CO_PDO_MAX_BITS);
		if (type_entry(e, dir, x->types, x->n_types, why, sizeof why))
			return fail(x, p, dir, "sub %u: %s", i, why);
	}
	p->n = (uint8_t)count;
	p->bytes = (uint8_t)((bits + 7u) / 8u);
	return 0;
}

static int read_layout(const struct layout_read *x, eds_pdo_file *out)
{
	const eds_pdo_reader *r = x->r;

	for (unsigned d = 0; d < 2; d++) {
		co_pdo_dir dir = d == 0 ? CO_PDO_RX : CO_PDO_TX;
		uint16_t comm0 = dir == CO_PDO_TX ? 0x1800u : 0x1400u;
		unsigned valid = 0;
		uint32_t cob;

		for (unsigned n = 0; n < CO_PDO_MAX; n++)
			valid += value_of(r, (uint16_t)(comm0 + n), 1, &cob) && !(cob >> 31);
		if (!valid)
			continue;
		out->pdo[dir] = calloc(valid, sizeof *out->pdo[dir]);
		if (!out->pdo[dir])
			return -ENOMEM;
		for (unsigned n = 0; n < CO_PDO_MAX; n++) {
			if (!value_of(r, (uint16_t)(comm0 + n), 1, &cob) || cob >> 31)
				continue;
			int rc = read_pdo(x, dir, n, cob, &out->pdo[dir][out->n[dir]]);
			if (rc)
				return rc;
			out->n[dir]++;
		}
	}
	return 0;
}

/* The file's objects with the overrides merged in (an override keeps the
 * file's access when it gives none). */
static int merge_types(const eds_pdo_reader *r, co_pdo_layout_type **out, size_t *n_out)
{
	const co_pdo_layout_type *overrides = r->overrides.list;
	size_t n = 0, n_overrides = r->overrides.n;
	co_pdo_layout_type *list = malloc((r->n + n_overrides + 1) * sizeof *list);
	const co_pdo_layout_type *dup;

	if (!list)
		return -ENOMEM;
	for (size_t i = 0; i < r->n; i++)
		if (!co_pdo_layout_type_find(overrides, n_overrides, r->obj[i].index,
					     r->obj[i].sub))
			list[n++] = r->obj[i];
	for (size_t i = 0; i < n_overrides; i++) {
		co_pdo_layout_type t = overrides[i];
		long k = find(r, t.index, t.sub);
		if (!t.access && k >= 0)
			t.access = r->obj[k].access;
		list[n++] = t;
	}
	(void)eds_pdo_types_sort(list, n, &dup); /* the file lists an object once */
	*out = list;
	*n_out = n;
	return 0;
}

int eds_pdo_reader_finish(eds_pdo_reader *r, const char *file, eds_pdo_file *layout,
			  eds_pdo_types *types, char *err, size_t errlen)
{
	co_pdo_layout_type *list = NULL;
	size_t n = 0;
	int rc;

	if (layout)
		memset(layout, 0, sizeof *layout);
	if (r->out_of_memory)
		return -ENOMEM;
	if ((rc = merge_types(r, &list, &n)))
		return rc;
	if (layout &&
	    (rc = read_layout(&(struct layout_read){ r, file, list, n, err, errlen }, layout))) {
		eds_pdo_file_free(layout);
		free(list);
		return rc;
	}
	if (types) {
		types->list = list;
		types->n = n;
	} else {
		free(list);
	}
	return 0;
}
