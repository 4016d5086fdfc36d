/* SPDX-License-Identifier: MIT */
/*
 * core/cdcf.h - the concise DCF (CiA 302-3, object 1F22h): the byte format
 * a manager downloads into one slave as its configuration. No I/O, no
 * allocation: the caller owns every buffer.
 *
 * Format, little-endian throughout:
 *   UNSIGNED32 count
 *   count times { UNSIGNED16 index, UNSIGNED8 sub-index, UNSIGNED32 size,
 *                 size bytes of data (the value in SDO wire format) }
 *
 * Checks on top of the framing: an index of 0000h is refused (not an
 * object), a size of 0 is refused (nothing to write; CiA 301 has no empty
 * SDO download), the count must match the entries exactly (no missing and
 * no trailing bytes). Which values an object accepts is the slave's
 * business (it answers with an abort); co_cdcf_check_od() checks entries
 * against a known dictionary when one is at hand.
 *
 * Every failure is described by a co_cdcf_diag: what is wrong, which entry
 * (1-based, 0 = the count field), at which byte offset of the buffer, and
 * the entry's index/sub/size as far as they could be read.
 *
 * Thread: any; functions are reentrant (state lives in the caller's
 * structures).
 */
#ifndef COGW_CORE_CDCF_H
#define COGW_CORE_CDCF_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/od.h"

#define CO_CDCF_COUNT_SIZE 4u
#define CO_CDCF_HEADER_SIZE 7u /* index (2) + sub (1) + size (4) */

typedef enum co_cdcf_error {
	CO_CDCF_OK = 0,
	CO_CDCF_ERR_NO_COUNT,      /* fewer than 4 bytes: no count field */
	CO_CDCF_ERR_HEADER_TRUNC,  /* an entry header is cut short */
	CO_CDCF_ERR_DATA_TRUNC,    /* an entry's data is cut short */
	CO_CDCF_ERR_INDEX_ZERO,    /* index 0000h */
	CO_CDCF_ERR_SIZE_ZERO,     /* size 0 */
	CO_CDCF_ERR_TRAILING,      /* bytes after the last counted entry */
	CO_CDCF_ERR_NO_OBJECT,     /* check_od: no such object */
	CO_CDCF_ERR_NO_SUB,        /* check_od: no such sub-index */
	CO_CDCF_ERR_SIZE_MISMATCH, /* check_od: size differs from the type */
	CO_CDCF_ERR_VALUE,         /* check_od: value refused by the OD */
	CO_CDCF_ERR_READ_ONLY,     /* check_od: entry is not writable */
} co_cdcf_error;

const char *co_cdcf_error_to_string(co_cdcf_error e);

typedef struct co_cdcf_diag {
	co_cdcf_error error;
	uint32_t entry; /* 1-based entry number; 0 = the count field */
	size_t offset;  /* byte offset in the buffer where the problem is */
	uint32_t count; /* the count field (when it could be read) */
	uint16_t index; /* the entry's fields, as far as read */
	uint8_t sub;
	uint32_t size;
	size_t have;    /* truncation: bytes that were left */
	uint32_t abort; /* check_od: the abort code an SDO write would get */
} co_cdcf_diag;

/* One entry; data points into the parsed buffer. */
typedef struct co_cdcf_entry {
	uint32_t number; /* 1-based */
	size_t offset;   /* offset of the entry header in the buffer */
	uint16_t index;
	uint8_t sub;
	uint32_t size;
	const uint8_t *data;
} co_cdcf_entry;

/*
 * Check the whole buffer. Returns 0 (and *count, if given) or -EINVAL with
 * *diag filled (diag may be NULL).
 */
int co_cdcf_check(const uint8_t *buf, size_t len, uint32_t *count, co_cdcf_diag *diag);

/*
 * Check every entry against a dictionary, as an SDO download of it would:
 * the entry exists, is writable (unless allow_read_only), and the value
 * passes co_od_check_value (size, BOOLEAN, limits). The buffer must pass
 * co_cdcf_check first (this calls it). 0 or -EINVAL with *diag.
 */
int co_cdcf_check_od(const uint8_t *buf, size_t len, const co_od *od, bool allow_read_only,
		     co_cdcf_diag *diag);

/*
 * Iterate over a buffer that passed co_cdcf_check (init checks it again,
 * so a caller cannot iterate over an unchecked buffer by mistake).
 */
typedef struct co_cdcf_iter {
	const uint8_t *buf;
	size_t len;
	size_t pos;
	uint32_t count;
	uint32_t next; /* 1-based number of the next entry */
} co_cdcf_iter;

int co_cdcf_iter_init(co_cdcf_iter *it, const uint8_t *buf, size_t len, co_cdcf_diag *diag);
/* Next entry into *e; false after the last one. */
bool co_cdcf_iter_next(co_cdcf_iter *it, co_cdcf_entry *e);

/*
 * Writer. With buf == NULL it only measures (len grows, nothing stored),
 * so a caller can size its buffer in a first pass.
 */
typedef struct co_cdcf_writer {
	uint8_t *buf;
	size_t cap;
	size_t len;
	uint32_t count;
	int error; /* first error (-EMSGSIZE, -EINVAL), sticky */
} co_cdcf_writer;

void co_cdcf_writer_init(co_cdcf_writer *w, uint8_t *buf, size_t cap);
/* Append one entry. -EINVAL for index 0 or size 0 or a NULL data pointer,
 * -EMSGSIZE if it does not fit (in measuring mode never), -EOVERFLOW past
 * 2^32-1 entries. An error is sticky: later adds fail with it too. */
int co_cdcf_writer_add(co_cdcf_writer *w, uint16_t index, uint8_t sub, const void *data,
		       uint32_t size);
/* Patch the count field. Returns the total length, or the sticky error. */
long co_cdcf_writer_finish(co_cdcf_writer *w);

/*
 * One line of text for a diag, e.g.
 *   "entry 3 (1800:02) at byte 25: data cut short (size 4, 2 bytes left)".
 * Returns the snprintf result.
 */
int co_cdcf_diag_format(const co_cdcf_diag *d, char *buf, size_t n);

#endif /* COGW_CORE_CDCF_H */
