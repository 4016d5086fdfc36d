/* SPDX-License-Identifier: MIT */
/*
 * core/cdcf.c - concise DCF parser, checker and writer (CiA 302-3, 1F22h).
 *
 * The parser walks the buffer once and stops at the first problem, so the
 * diag names the first entry a manager could not have written. Offsets
 * are computed with subtraction against what is left, never by adding a
 * size read from the buffer to a position (a 32-bit size near 2^32 must
 * not wrap a size_t on 32-bit targets).
 */
#include "core/cdcf.h"
#include "core/frame.h"
#include "core/sdo.h"

#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <string.h>

const char *co_cdcf_error_to_string(co_cdcf_error e)
{
	switch (e) {
	case CO_CDCF_OK:
		return "ok";
	case CO_CDCF_ERR_NO_COUNT:
		return "no entry count (fewer than 4 bytes)";
	case CO_CDCF_ERR_HEADER_TRUNC:
		return "entry header cut short";
	case CO_CDCF_ERR_DATA_TRUNC:
		return "data cut short";
	case CO_CDCF_ERR_INDEX_ZERO:
		return "index 0000h is not an object";
	case CO_CDCF_ERR_SIZE_ZERO:
		return "size 0 (nothing to write)";
	case CO_CDCF_ERR_TRAILING:
		return "bytes after the last counted entry";
	case CO_CDCF_ERR_NO_OBJECT:
		return "object does not exist";
	case CO_CDCF_ERR_NO_SUB:
		return "sub-index does not exist";
	case CO_CDCF_ERR_SIZE_MISMATCH:
		return "size does not match the data type";
	case CO_CDCF_ERR_VALUE:
		return "value refused";
	case CO_CDCF_ERR_READ_ONLY:
		return "object is not writable";
	}
	return "unknown error";
}

static int fail(co_cdcf_diag *d, co_cdcf_error err, uint32_t entry, size_t offset)
{
	if (d) {
		d->error = err;
		d->entry = entry;
		d->offset = offset;
	}
	return -EINVAL;
}

/*
 * Parse the entry at *pos (number n). On success fills e and advances
 * *pos. Leaves index/sub/size in the diag as far as they were read.
 */
static int parse_entry(const uint8_t *buf, size_t len, size_t *pos, uint32_t n, co_cdcf_entry *e,
		       co_cdcf_diag *d)
{
	size_t at = *pos, left = len - at;

	if (left < CO_CDCF_HEADER_SIZE) {
		if (d) {
			d->have = left;
			if (left >= 2)
				d->index = co_get_le16(buf + at);
			if (left >= 3)
				d->sub = buf[at + 2];
		}
		return fail(d, CO_CDCF_ERR_HEADER_TRUNC, n, at);
	}
	e->number = n;
	e->offset = at;
	e->index = co_get_le16(buf + at);
	e->sub = buf[at + 2];
	e->size = co_get_le32(buf + at + 3);
	if (d) {
		d->index = e->index;
		d->sub = e->sub;
		d->size = e->size;
	}
	if (e->index == 0)
		return fail(d, CO_CDCF_ERR_INDEX_ZERO, n, at);
	if (e->size == 0)
		return fail(d, CO_CDCF_ERR_SIZE_ZERO, n, at + 3);
	left -= CO_CDCF_HEADER_SIZE;
	if (e->size > left) {
		if (d)
			d->have = left;
		return fail(d, CO_CDCF_ERR_DATA_TRUNC, n, at + CO_CDCF_HEADER_SIZE);
	}
	e->data = buf + at + CO_CDCF_HEADER_SIZE;
	*pos = at + CO_CDCF_HEADER_SIZE + e->size;
	return 0;
}

int co_cdcf_check(const uint8_t *buf, size_t len, uint32_t *count, co_cdcf_diag *diag)
{
	co_cdcf_entry e;
	uint32_t n;
	size_t pos;

	if (diag)
		memset(diag, 0, sizeof(*diag));
	if (!buf || len < CO_CDCF_COUNT_SIZE) {
		if (diag)
			diag->have = buf ? len : 0;
		return fail(diag, CO_CDCF_ERR_NO_COUNT, 0, 0);
	}
	n = co_get_le32(buf);
	if (diag)
		diag->count = n;
	pos = CO_CDCF_COUNT_SIZE;
	for (uint32_t i = 1; i <= n && i != 0; i++) {
		if (parse_entry(buf, len, &pos, i, &e, diag))
			return -EINVAL;
		if (i == UINT32_MAX)
			break;
	}
	if (pos != len) {
		if (diag) {
			diag->have = len - pos;
			diag->index = 0;
			diag->sub = 0;
			diag->size = 0;
		}
		return fail(diag, CO_CDCF_ERR_TRAILING, n, pos);
	}
	if (count)
		*count = n;
	return 0;
}

int co_cdcf_iter_init(co_cdcf_iter *it, const uint8_t *buf, size_t len, co_cdcf_diag *diag)
{
	uint32_t n = 0;
	int rc = co_cdcf_check(buf, len, &n, diag);

	memset(it, 0, sizeof(*it));
	if (rc)
		return rc;
	it->buf = buf;
	it->len = len;
	it->pos = CO_CDCF_COUNT_SIZE;
	it->count = n;
	it->next = 1;
	return 0;
}

bool co_cdcf_iter_next(co_cdcf_iter *it, co_cdcf_entry *e)
{
	if (!it->buf || it->next == 0 || it->next > it->count)
		return false;
	if (parse_entry(it->buf, it->len, &it->pos, it->next, e, NULL))
		return false; /* cannot happen after check; be safe anyway */
	it->next = it->next == UINT32_MAX ? 0 : it->next + 1;
	return true;
}

int co_cdcf_check_od(const uint8_t *buf, size_t len, const co_od *od, bool allow_read_only,
		     co_cdcf_diag *diag)
{
	co_cdcf_iter it;
	co_cdcf_entry e;
	int rc = co_cdcf_iter_init(&it, buf, len, diag);

	if (rc)
		return rc;
	while (co_cdcf_iter_next(&it, &e)) {
		uint32_t abort = 0;
		const co_od_entry *oe = co_od_find_ex(od, e.index, e.sub, &abort);

		if (diag) {
			diag->index = e.index;
			diag->sub = e.sub;
			diag->size = e.size;
		}
		if (!oe) {
			if (diag)
				diag->abort = abort;
			return fail(diag,
				    abort == SDO_AB_NO_OBJ ? CO_CDCF_ERR_NO_OBJECT
							   : CO_CDCF_ERR_NO_SUB,
				    e.number, e.offset);
		}
		if (!allow_read_only && !(oe->access & CO_ACC_WRITE)) {
			if (diag)
				diag->abort = SDO_AB_READ_ONLY;
			return fail(diag, CO_CDCF_ERR_READ_ONLY, e.number, e.offset);
		}
		abort = co_od_check_value(oe, e.data, e.size);
		if (abort) {
			bool size = abort == SDO_AB_TYPE_LEN || abort == SDO_AB_LEN_HIGH ||
				    abort == SDO_AB_LEN_LOW;
			if (diag)
				diag->abort = abort;
			return fail(diag, size ? CO_CDCF_ERR_SIZE_MISMATCH : CO_CDCF_ERR_VALUE,
				    e.number, e.offset + (size ? 3 : CO_CDCF_HEADER_SIZE));
		}
	}
	return 0;
}

void co_cdcf_writer_init(co_cdcf_writer *w, uint8_t *buf, size_t cap)
{
	memset(w, 0, sizeof(*w));
	w->buf = buf;
	w->cap = cap;
	w->len = CO_CDCF_COUNT_SIZE;
	if (buf && cap < CO_CDCF_COUNT_SIZE)
		w->error = -EMSGSIZE;
}

int co_cdcf_writer_add(co_cdcf_writer *w, uint16_t index, uint8_t sub, const void *data,
		       uint32_t size)
{
	if (w->error)
		return w->error;
	if (index == 0 || size == 0 || !data)
		return w->error = -EINVAL;
	if (w->count == UINT32_MAX)
		return w->error = -EOVERFLOW;
	if (w->buf) {
		if (w->cap - w->len < CO_CDCF_HEADER_SIZE ||
		    w->cap - w->len - CO_CDCF_HEADER_SIZE < size)
			return w->error = -EMSGSIZE;
		uint8_t *p = w->buf + w->len;
		p[0] = (uint8_t)index;
		p[1] = (uint8_t)(index >> 8);
		p[2] = sub;
		co_put_le32(p + 3, size);
		memcpy(p + CO_CDCF_HEADER_SIZE, data, size);
	} else if (SIZE_MAX - w->len - CO_CDCF_HEADER_SIZE < size) {
		return w->error = -EMSGSIZE;
	}
	w->len += CO_CDCF_HEADER_SIZE + size;
	w->count++;
	return 0;
}

long co_cdcf_writer_finish(co_cdcf_writer *w)
{
	if (w->error)
		return w->error;
	if (w->len > (size_t)LONG_MAX)
		return -EMSGSIZE;
	if (w->buf)
		co_put_le32(w->buf, w->count);
	return (long)w->len;
}

int co_cdcf_diag_format(const co_cdcf_diag *d, char *buf, size_t n)
{
	const char *what = co_cdcf_error_to_string(d->error);

	switch (d->error) {
	case CO_CDCF_OK:
		return snprintf(buf, n, "ok");
	case CO_CDCF_ERR_NO_COUNT:
		return snprintf(buf, n, "at byte 0: %s: %zu bytes", what, d->have);
	case CO_CDCF_ERR_HEADER_TRUNC:
		return snprintf(buf, n, "entry %u of %u at byte %zu: %s (%zu of %u header bytes)",
				(unsigned)d->entry, (unsigned)d->count, d->offset, what, d->have,
				CO_CDCF_HEADER_SIZE);
	case CO_CDCF_ERR_DATA_TRUNC:
		return snprintf(
			buf, n,
			"entry %u of %u (%04X:%02X) at byte %zu: %s (size %u, %zu bytes left)",
			(unsigned)d->entry, (unsigned)d->count, d->index, d->sub, d->offset, what,
			(unsigned)d->size, d->have);
	case CO_CDCF_ERR_TRAILING:
		return snprintf(buf, n, "at byte %zu: %zu %s (count %u)", d->offset, d->have, what,
				(unsigned)d->count);
	case CO_CDCF_ERR_INDEX_ZERO:
	case CO_CDCF_ERR_SIZE_ZERO:
		return snprintf(buf, n, "entry %u (%04X:%02X) at byte %zu: %s", (unsigned)d->entry,
				d->index, d->sub, d->offset, what);
	case CO_CDCF_ERR_NO_OBJECT:
	case CO_CDCF_ERR_NO_SUB:
	case CO_CDCF_ERR_SIZE_MISMATCH:
	case CO_CDCF_ERR_VALUE:
	case CO_CDCF_ERR_READ_ONLY:
		return snprintf(buf, n,
				"entry %u (%04X:%02X, size %u) at byte %zu: %s (abort %08X)",
				(unsigned)d->entry, d->index, d->sub, (unsigned)d->size, d->offset,
				what, (unsigned)d->abort);
	}
	return snprintf(buf, n, "%s", what);
}
