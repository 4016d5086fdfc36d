/* SPDX-License-Identifier: MIT */
/*
 * Object dictionary: a sorted array of pointers to individually allocated
 * entries. Why this shape:
 * - binary search over one array keyed by (index << 8 | sub) answers both
 *   "which entry" and "does the index exist at all" (the neighbours of the
 *   insertion point) - the two cases SDO must tell apart (0x06020000 vs
 *   0x06090011);
 * - entries never move, so services (PDO mapping, SDO channels) can keep
 *   pointers across later additions from the JSON configuration;
 * - adding is O(n) (a memmove of pointers), lookup O(log n); adding happens
 *   at configuration time, lookup per frame.
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/od.h"
#include "core/sdo.h"

struct co_od {
	co_od_entry **v;
	size_t n;
	size_t cap;
};

/* ---- types --------------------------------------------------------------- */

const char *co_type_to_string(co_type t)
{
	switch (t) {
	case CO_T_BOOLEAN:
		return "BOOLEAN";
	case CO_T_INTEGER8:
		return "INTEGER8";
	case CO_T_INTEGER16:
		return "INTEGER16";
	case CO_T_INTEGER24:
		return "INTEGER24";
	case CO_T_INTEGER32:
		return "INTEGER32";
	case CO_T_INTEGER40:
		return "INTEGER40";
	case CO_T_INTEGER48:
		return "INTEGER48";
	case CO_T_INTEGER56:
		return "INTEGER56";
	case CO_T_INTEGER64:
		return "INTEGER64";
	case CO_T_UNSIGNED8:
		return "UNSIGNED8";
	case CO_T_UNSIGNED16:
		return "UNSIGNED16";
	case CO_T_UNSIGNED24:
		return "UNSIGNED24";
	case CO_T_UNSIGNED32:
		return "UNSIGNED32";
	case CO_T_UNSIGNED40:
		return "UNSIGNED40";
	case CO_T_UNSIGNED48:
		return "UNSIGNED48";
	case CO_T_UNSIGNED56:
		return "UNSIGNED56";
	case CO_T_UNSIGNED64:
		return "UNSIGNED64";
	case CO_T_REAL32:
		return "REAL32";
	case CO_T_REAL64:
		return "REAL64";
	case CO_T_VISIBLE_STRING:
		return "VISIBLE_STRING";
	case CO_T_OCTET_STRING:
		return "OCTET_STRING";
	case CO_T_UNICODE_STRING:
		return "UNICODE_STRING";
	case CO_T_TIME_OF_DAY:
		return "TIME_OF_DAY";
	case CO_T_TIME_DIFFERENCE:
		return "TIME_DIFFERENCE";
	case CO_T_DOMAIN:
		return "DOMAIN";
	}
	return "?";
}

uint32_t co_type_size(co_type t)
{
	switch (t) {
	case CO_T_BOOLEAN:
	case CO_T_INTEGER8:
	case CO_T_UNSIGNED8:
		return 1;
	case CO_T_INTEGER16:
	case CO_T_UNSIGNED16:
		return 2;
	case CO_T_INTEGER24:
	case CO_T_UNSIGNED24:
		return 3;
	case CO_T_INTEGER32:
	case CO_T_UNSIGNED32:
	case CO_T_REAL32:
		return 4;
	case CO_T_INTEGER40:
	case CO_T_UNSIGNED40:
		return 5;
	case CO_T_INTEGER48:
	case CO_T_UNSIGNED48:
	case CO_T_TIME_OF_DAY: /* 28-bit ms + 4 reserved bits + 16-bit days */
	case CO_T_TIME_DIFFERENCE:
		return 6;
	case CO_T_INTEGER56:
	case CO_T_UNSIGNED56:
		return 7;
	case CO_T_INTEGER64:
	case CO_T_UNSIGNED64:
	case CO_T_REAL64:
		return 8;
	case CO_T_VISIBLE_STRING:
	case CO_T_OCTET_STRING:
	case CO_T_UNICODE_STRING:
	case CO_T_DOMAIN:
		return 0;
	}
	return 0;
}

bool co_type_is_variable(co_type t)
{
	return t == CO_T_VISIBLE_STRING || t == CO_T_OCTET_STRING || t == CO_T_UNICODE_STRING ||
	       t == CO_T_DOMAIN;
}

bool co_type_is_valid(co_type t)
{
	return co_type_size(t) != 0 || co_type_is_variable(t);
}

bool co_type_is_signed(co_type t)
{
	switch (t) {
	case CO_T_INTEGER8:
	case CO_T_INTEGER16:
	case CO_T_INTEGER24:
	case CO_T_INTEGER32:
	case CO_T_INTEGER40:
	case CO_T_INTEGER48:
	case CO_T_INTEGER56:
	case CO_T_INTEGER64:
		return true;
	default:
		return false;
	}
}

bool co_type_is_real(co_type t)
{
	return t == CO_T_REAL32 || t == CO_T_REAL64;
}

/* Integer-like: has an ordering on which limits make sense. */
static bool type_is_integer(co_type t)
{
	return co_type_size(t) != 0 && !co_type_is_real(t) && t != CO_T_TIME_OF_DAY &&
	       t != CO_T_TIME_DIFFERENCE;
}

const char *co_obj_code_to_string(co_obj_code c)
{
	switch (c) {
	case CO_OBJ_NULL:
		return "NULL";
	case CO_OBJ_DOMAIN:
		return "DOMAIN";
	case CO_OBJ_DEFTYPE:
		return "DEFTYPE";
	case CO_OBJ_DEFSTRUCT:
		return "DEFSTRUCT";
	case CO_OBJ_VAR:
		return "VAR";
	case CO_OBJ_ARRAY:
		return "ARRAY";
	case CO_OBJ_RECORD:
		return "RECORD";
	}
	return "?";
}

const char *co_od_origin_to_string(co_od_origin o)
{
	switch (o) {
	case CO_OD_ORIGIN_LOCAL:
		return "local";
	case CO_OD_ORIGIN_SDO:
		return "sdo";
	case CO_OD_ORIGIN_PDO:
		return "pdo";
	case CO_OD_ORIGIN_RESET:
		return "reset";
	}
	return "?";
}

/* ---- raw little-endian helpers -------------------------------------------- */

static uint64_t le_load(const uint8_t *p, uint32_t n)
{
	uint64_t v = 0;

	for (uint32_t i = n; i-- > 0;)
		v = (v << 8) | p[i];
	return v;
}

static void le_store(uint8_t *p, uint32_t n, uint64_t v)
{
	for (uint32_t i = 0; i < n; i++, v >>= 8)
		p[i] = (uint8_t)v;
}

static int64_t sign_extend(uint64_t v, uint32_t bytes)
{
	if (bytes >= 8)
		return (int64_t)v;
	unsigned shift = 64u - 8u * bytes;
	return (int64_t)(v << shift) >> shift;
}

/* ---- lifetime ---------------------------------------------------------- */

int co_od_create(co_od **out, size_t capacity_hint)
{
	co_od *od = calloc(1, sizeof(*od));

	if (!od)
		return -ENOMEM;
	od->cap = capacity_hint ? capacity_hint : 64;
	od->v = calloc(od->cap, sizeof(*od->v));
	if (!od->v) {
		free(od);
		return -ENOMEM;
	}
	*out = od;
	return 0;
}

static void entry_free(co_od_entry *e)
{
	if (!e)
		return;
	if (e->data != e->val)
		free(e->data);
	free(e->def_data);
	free(e->name);
	free(e);
}

void co_od_destroy(co_od *od)
{
	if (!od)
		return;
	for (size_t i = 0; i < od->n; i++)
		entry_free(od->v[i]);
	free(od->v);
	free(od);
}

/* ---- lookup ------------------------------------------------------------ */

static uint32_t key_of(uint16_t index, uint8_t sub)
{
	return ((uint32_t)index << 8) | sub;
}

/* First position whose key is >= key. */
static size_t lower_bound(const co_od *od, uint32_t key)
{
	size_t lo = 0, hi = od->n;

	while (lo < hi) {
		size_t mid = lo + (hi - lo) / 2;
		if (key_of(od->v[mid]->index, od->v[mid]->sub) < key)
			lo = mid + 1;
		else
			hi = mid;
	}
	return lo;
}

co_od_entry *co_od_find_ex(const co_od *od, uint16_t index, uint8_t sub, uint32_t *abort)
{
	size_t pos = lower_bound(od, key_of(index, sub));

	if (pos < od->n && od->v[pos]->index == index) {
		if (od->v[pos]->sub == sub) {
			if (abort)
				*abort = 0;
			return od->v[pos];
		}
		if (abort)
			*abort = SDO_AB_NO_SUB;
		return NULL;
	}
	if (abort) {
		/* The entry before the insertion point may hold a lower sub of
		 * the same index (sub-index gaps are allowed). */
		bool idx = pos > 0 && od->v[pos - 1]->index == index;
		*abort = idx ? SDO_AB_NO_SUB : SDO_AB_NO_OBJ;
	}
	return NULL;
}

co_od_entry *co_od_find(const co_od *od, uint16_t index, uint8_t sub)
{
	return co_od_find_ex(od, index, sub, NULL);
}

bool co_od_has_index(const co_od *od, uint16_t index)
{
	size_t pos = lower_bound(od, key_of(index, 0));

	return pos < od->n && od->v[pos]->index == index;
}

size_t co_od_count(const co_od *od)
{
	return od->n;
}

co_od_entry *co_od_at(const co_od *od, size_t pos)
{
	return pos < od->n ? od->v[pos] : NULL;
}

/* ---- building ---------------------------------------------------------- */

static int desc_check(const co_od_desc *d)
{
	co_type t = (co_type)d->type;

	if (!co_type_is_valid(t))
		return -EINVAL;
	if (co_type_is_variable(t)) {
		if (d->def_size > d->max_size || (d->def_size && !d->def))
			return -EINVAL;
		if (d->min || d->max)
			return -EINVAL;
	} else if (d->def && d->def_size != co_type_size(t)) {
		return -EINVAL;
	}
	return 0;
}

static co_od_entry *entry_new(const co_od_desc *d)
{
	co_od_entry *e = calloc(1, sizeof(*e));
	co_type t = (co_type)d->type;

	if (!e)
		return NULL;
	e->index = d->index;
	e->sub = d->sub;
	e->obj_code = d->obj_code ? d->obj_code : CO_OBJ_VAR;
	e->type = d->type;
	e->access = d->access;
	if (co_type_is_variable(t)) {
		/* +1: a VISIBLE_STRING stays NUL-terminated for C readers. */
		e->data = calloc(1, (size_t)d->max_size + 1);
		e->max_size = d->max_size;
		if (!e->data)
			goto fail;
		if (d->def_size) {
			e->def_data = malloc(d->def_size);
			if (!e->def_data)
				goto fail;
			memcpy(e->def_data, d->def, d->def_size);
			e->def_size = d->def_size;
		}
	} else {
		e->data = e->val;
		e->size = e->max_size = co_type_size(t);
		if (d->def)
			memcpy(e->def, d->def, e->size);
		if (d->min || d->max) {
			e->has_limits = 1;
			/* A missing bound is the type's extreme value. */
			uint64_t lo = 0, hi = ~0ull;
			if (co_type_is_signed(t)) {
				lo = (uint64_t)sign_extend(1ull << (8 * e->size - 1), e->size);
				hi = ~lo;
			}
			le_store(e->min, e->size, lo);
			le_store(e->max, e->size, hi);
			if (co_type_is_real(t)) {
				/* -inf / +inf */
				uint64_t ninf = e->size == 4 ? 0xFF800000u : 0xFFF0000000000000ull;
				uint64_t pinf = e->size == 4 ? 0x7F800000u : 0x7FF0000000000000ull;
				le_store(e->min, e->size, ninf);
				le_store(e->max, e->size, pinf);
			}
			if (d->min)
				memcpy(e->min, d->min, e->size);
			if (d->max)
				memcpy(e->max, d->max, e->size);
		}
	}
	if (d->name) {
		e->name = strdup(d->name);
		if (!e->name)
			goto fail;
	}
	co_od_entry_reset(e);
	return e;
fail:
	entry_free(e);
	return NULL;
}

static int od_grow(co_od *od)
{
	size_t cap = od->cap * 2;
	co_od_entry **v = realloc(od->v, cap * sizeof(*v));

	if (!v)
		return -ENOMEM;
	od->v = v;
	od->cap = cap;
	return 0;
}

int co_od_add(co_od *od, const co_od_desc *d, co_od_entry **out)
{
	int rc = desc_check(d);
	size_t pos;
	co_od_entry *e;

	if (rc)
		return rc;
	pos = lower_bound(od, key_of(d->index, d->sub));
	if (pos < od->n && od->v[pos]->index == d->index && od->v[pos]->sub == d->sub)
		return -EEXIST;
	if (od->n == od->cap && (rc = od_grow(od)) != 0)
		return rc;
	e = entry_new(d);
	if (!e)
		return -ENOMEM;
	memmove(&od->v[pos + 1], &od->v[pos], (od->n - pos) * sizeof(*od->v));
	od->v[pos] = e;
	od->n++;
	if (out)
		*out = e;
	return 0;
}

int co_od_add_num(co_od *od, uint16_t index, uint8_t sub, co_type type, uint16_t access,
		  uint64_t def_bits, co_od_entry **out)
{
	uint8_t def[8];
	uint32_t n = co_type_size(type);

	if (n == 0)
		return -EINVAL;
	le_store(def, n, def_bits);
	co_od_desc d = { .index = index,
			 .sub = sub,
			 .type = (uint8_t)type,
			 .access = access,
			 .def = def,
			 .def_size = n };
	return co_od_add(od, &d, out);
}

int co_od_ensure_num(co_od *od, uint16_t index, uint8_t sub, co_type type, uint16_t access,
		     uint64_t def_bits, uint8_t obj_code)
{
	co_od_entry *e;
	int rc = co_od_add_num(od, index, sub, type, access, def_bits, &e);

	if (rc == -EEXIST)
		return 0;
	if (rc == 0 && obj_code)
		e->obj_code = obj_code;
	return rc;
}

int co_od_add_bytes(co_od *od, uint16_t index, uint8_t sub, co_type type, uint16_t access,
		    uint32_t max_size, const void *def, uint32_t def_size, co_od_entry **out)
{
	co_od_desc d = { .index = index,
			 .sub = sub,
			 .type = (uint8_t)type,
			 .access = access,
			 .max_size = max_size,
			 .def = def,
			 .def_size = def_size };

	if (!co_type_is_variable(type))
		return -EINVAL;
	return co_od_add(od, &d, out);
}

int co_od_add_array(co_od *od, uint16_t index, co_type type, uint8_t n, uint16_t access,
		    uint64_t def_bits)
{
	co_od_entry *e;
	int rc = co_od_add_num(od, index, 0, CO_T_UNSIGNED8, CO_ACC_RO, n, &e);

	if (rc)
		return rc;
	e->obj_code = CO_OBJ_ARRAY;
	for (unsigned s = 1; s <= n; s++) {
		rc = co_od_add_num(od, index, (uint8_t)s, type, access, def_bits, &e);
		if (rc)
			return rc;
		e->obj_code = CO_OBJ_ARRAY;
	}
	return 0;
}

int co_od_entry_set_limits(co_od_entry *e, uint64_t min_bits, uint64_t max_bits)
{
	if (co_type_is_variable((co_type)e->type))
		return -EINVAL;
	le_store(e->min, e->size, min_bits);
	le_store(e->max, e->size, max_bits);
	e->has_limits = 1;
	return 0;
}

void co_od_entry_set_hooks(co_od_entry *e, const co_od_hooks *hooks, void *ctx)
{
	e->hooks = hooks;
	e->hook_ctx = ctx;
}

int co_od_set_hooks(co_od *od, uint16_t index, uint8_t sub, const co_od_hooks *hooks, void *ctx)
{
	co_od_entry *e = co_od_find(od, index, sub);

	if (!e)
		return -ENOENT;
	co_od_entry_set_hooks(e, hooks, ctx);
	return 0;
}

/* ---- raw values -------------------------------------------------------- */

uint64_t co_od_entry_raw(const co_od_entry *e)
{
	return le_load(e->data, e->size < 8 ? e->size : 8);
}

void co_od_entry_set_raw(co_od_entry *e, uint64_t bits)
{
	if (!co_type_is_variable((co_type)e->type))
		le_store(e->data, e->size, bits);
}

static void store_bytes(co_od_entry *e, const uint8_t *buf, uint32_t len)
{
	/* buf == e->data: an SDO download streamed in place (sdo_server.c). */
	if (len && buf != e->data)
		memcpy(e->data, buf, len);
	if (co_type_is_variable((co_type)e->type)) {
		e->size = len;
		e->data[len] = 0;
	}
}

int co_od_entry_set_bytes(co_od_entry *e, const void *buf, uint32_t len)
{
	if (!co_type_is_variable((co_type)e->type) && len != e->size)
		return -EINVAL;
	if (len > e->max_size)
		return -EMSGSIZE;
	store_bytes(e, buf, len);
	return 0;
}

/* ---- typed helpers ------------------------------------------------------ */

static int get_int(const co_od *od, uint16_t index, uint8_t sub, uint32_t width, bool want_signed,
		   uint64_t *bits)
{
	const co_od_entry *e = co_od_find(od, index, sub);

	if (!e)
		return -ENOENT;
	if (!type_is_integer((co_type)e->type) || e->size > width)
		return -EINVAL;
	uint64_t v = co_od_entry_raw(e);
	if (want_signed && co_type_is_signed((co_type)e->type))
		v = (uint64_t)sign_extend(v, e->size);
	*bits = v;
	return 0;
}

static int set_int(co_od *od, uint16_t index, uint8_t sub, uint64_t v, bool is_signed)
{
	co_od_entry *e = co_od_find(od, index, sub);

	if (!e)
		return -ENOENT;
	if (!type_is_integer((co_type)e->type))
		return -EINVAL;
	if (e->size < 8) {
		if (is_signed) {
			if (sign_extend(v, e->size) != (int64_t)v)
				return -ERANGE;
		} else if (v >> (8 * e->size)) {
			return -ERANGE;
		}
	}
	if (e->type == CO_T_BOOLEAN && v > 1)
		return -ERANGE;
	le_store(e->data, e->size, v);
	return 0;
}

#define OD_GET_UINT(name, ctype)                                               \
	int co_od_get_##name(const co_od *od, uint16_t i, uint8_t s, ctype *v) \
	{                                                                      \
		uint64_t b;                                                    \
		int rc = get_int(od, i, s, sizeof(ctype), false, &b);          \
		if (rc == 0)                                                   \
			*v = (ctype)b;                                         \
		return rc;                                                     \
	}                                                                      \
	int co_od_set_##name(co_od *od, uint16_t i, uint8_t s, ctype v)        \
	{                                                                      \
		return set_int(od, i, s, (uint64_t)v, false);                  \
	}

#define OD_GET_SINT(name, ctype)                                               \
	int co_od_get_##name(const co_od *od, uint16_t i, uint8_t s, ctype *v) \
	{                                                                      \
		uint64_t b;                                                    \
		int rc = get_int(od, i, s, sizeof(ctype), true, &b);           \
		if (rc == 0)                                                   \
			*v = (ctype)(int64_t)b;                                \
		return rc;                                                     \
	}                                                                      \
	int co_od_set_##name(co_od *od, uint16_t i, uint8_t s, ctype v)        \
	{                                                                      \
		return set_int(od, i, s, (uint64_t)(int64_t)v, true);          \
	}

OD_GET_UINT(u8, uint8_t)
OD_GET_UINT(u16, uint16_t)
OD_GET_UINT(u32, uint32_t)
OD_GET_UINT(u64, uint64_t)
OD_GET_SINT(i8, int8_t)
OD_GET_SINT(i16, int16_t)
OD_GET_SINT(i32, int32_t)
OD_GET_SINT(i64, int64_t)

int co_od_get_r32(const co_od *od, uint16_t index, uint8_t sub, float *v)
{
	const co_od_entry *e = co_od_find(od, index, sub);
	uint32_t bits;

	if (!e)
		return -ENOENT;
	if (e->type != CO_T_REAL32)
		return -EINVAL;
	bits = (uint32_t)co_od_entry_raw(e);
	memcpy(v, &bits, sizeof(*v));
	return 0;
}

int co_od_get_r64(const co_od *od, uint16_t index, uint8_t sub, double *v)
{
	const co_od_entry *e = co_od_find(od, index, sub);
	uint64_t bits;

	if (!e)
		return -ENOENT;
	if (e->type != CO_T_REAL64)
		return -EINVAL;
	bits = co_od_entry_raw(e);
	memcpy(v, &bits, sizeof(*v));
	return 0;
}

int co_od_set_r32(co_od *od, uint16_t index, uint8_t sub, float v)
{
	co_od_entry *e = co_od_find(od, index, sub);
	uint32_t bits;

	if (!e)
		return -ENOENT;
	if (e->type != CO_T_REAL32)
		return -EINVAL;
	memcpy(&bits, &v, sizeof(bits));
	co_od_entry_set_raw(e, bits);
	return 0;
}

int co_od_set_r64(co_od *od, uint16_t index, uint8_t sub, double v)
{
	co_od_entry *e = co_od_find(od, index, sub);
	uint64_t bits;

	if (!e)
		return -ENOENT;
	if (e->type != CO_T_REAL64)
		return -EINVAL;
	memcpy(&bits, &v, sizeof(bits));
	co_od_entry_set_raw(e, bits);
	return 0;
}

int co_od_get_bytes(const co_od *od, uint16_t index, uint8_t sub, void *buf, uint32_t cap,
		    uint32_t *len)
{
	const co_od_entry *e = co_od_find(od, index, sub);

	if (!e)
		return -ENOENT;
	*len = e->size;
	if (e->size > cap)
		return -EMSGSIZE;
	if (e->size)
		memcpy(buf, e->data, e->size);
	return 0;
}

int co_od_set_bytes(co_od *od, uint16_t index, uint8_t sub, const void *buf, uint32_t len)
{
	co_od_entry *e = co_od_find(od, index, sub);

	if (!e)
		return -ENOENT;
	return co_od_entry_set_bytes(e, buf, len);
}

/* ---- checked writes ------------------------------------------------------ */

static int cmp_value(co_type t, uint32_t n, const uint8_t *a, const uint8_t *b)
{
	uint64_t ua = le_load(a, n), ub = le_load(b, n);

	if (t == CO_T_REAL32 || t == CO_T_REAL64) {
		double da, db;
		if (t == CO_T_REAL32) {
			float fa, fb;
			uint32_t xa = (uint32_t)ua, xb = (uint32_t)ub;
			memcpy(&fa, &xa, 4);
			memcpy(&fb, &xb, 4);
			da = fa;
			db = fb;
		} else {
			memcpy(&da, &ua, 8);
			memcpy(&db, &ub, 8);
		}
		return da < db ? -1 : da > db ? 1 : 0;
	}
	if (co_type_is_signed(t)) {
		int64_t sa = sign_extend(ua, n), sb = sign_extend(ub, n);
		return sa < sb ? -1 : sa > sb ? 1 : 0;
	}
	return ua < ub ? -1 : ua > ub ? 1 : 0;
}

static bool is_nan(co_type t, const uint8_t *p)
{
	if (t == CO_T_REAL32) {
		uint32_t b = (uint32_t)le_load(p, 4);
		return (b & 0x7F800000u) == 0x7F800000u && (b & 0x007FFFFFu);
	}
	if (t == CO_T_REAL64) {
		uint64_t b = le_load(p, 8);
		return (b & 0x7FF0000000000000ull) == 0x7FF0000000000000ull &&
		       (b & 0x000FFFFFFFFFFFFFull);
	}
	return false;
}

uint32_t co_od_check_value(const co_od_entry *e, const uint8_t *data, uint32_t len)
{
	co_type t = (co_type)e->type;

	if (co_type_is_variable(t))
		return len > e->max_size ? SDO_AB_LEN_HIGH : 0;
	if (len > e->size)
		return SDO_AB_LEN_HIGH;
	if (len < e->size)
		return SDO_AB_LEN_LOW;
	if (t == CO_T_BOOLEAN && data[0] > 1)
		return SDO_AB_VALUE;
	if (e->has_limits) {
		if (is_nan(t, data))
			return SDO_AB_VALUE;
		if (cmp_value(t, e->size, data, e->min) < 0)
			return SDO_AB_VALUE_LOW;
		if (cmp_value(t, e->size, data, e->max) > 0)
			return SDO_AB_VALUE_HIGH;
	}
	return 0;
}

void co_od_commit(co_od_entry *e, const uint8_t *data, uint32_t len, const co_od_access *a)
{
	store_bytes(e, data, len);
	if (e->hooks && e->hooks->after_write)
		e->hooks->after_write(e->hook_ctx, e, a);
}

uint32_t co_od_write(co_od_entry *e, const uint8_t *data, uint32_t len, const co_od_access *a)
{
	uint32_t ab = co_od_check_value(e, data, len);

	if (ab)
		return ab;
	if (e->hooks && e->hooks->check_write) {
		co_od_access acc = *a;
		acc.data = data;
		acc.size = len;
		ab = e->hooks->check_write(e->hook_ctx, e, &acc);
		if (ab)
			return ab;
	}
	co_od_commit(e, data, len, a);
	return 0;
}

/* ---- defaults ---------------------------------------------------------- */

void co_od_entry_reset(co_od_entry *e)
{
	if (co_type_is_variable((co_type)e->type))
		store_bytes(e, e->def_data, e->def_size);
	else
		memcpy(e->val, e->def, e->size);
}

void co_od_reset_range(co_od *od, uint16_t first, uint16_t last)
{
	for (size_t i = lower_bound(od, key_of(first, 0)); i < od->n && od->v[i]->index <= last;
	     i++)
		co_od_entry_reset(od->v[i]);
}

void co_od_entry_set_default_raw(co_od_entry *e, uint64_t bits)
{
	if (!co_type_is_variable((co_type)e->type))
		le_store(e->def, e->size, bits);
}

int co_od_entry_set_default_bytes(co_od_entry *e, const void *buf, uint32_t len)
{
	uint8_t *p = NULL;

	if (!co_type_is_variable((co_type)e->type)) {
		if (len != e->size || !buf)
			return -EINVAL;
		memcpy(e->def, buf, len);
		return 0;
	}
	if (len > e->max_size)
		return -EMSGSIZE;
	if (len && !buf)
		return -EINVAL;
	if (len) {
		p = malloc(len);
		if (!p)
			return -ENOMEM;
		memcpy(p, buf, len);
	}
	free(e->def_data);
	e->def_data = p;
	e->def_size = len;
	return 0;
}
