/* SPDX-License-Identifier: MIT */
/*
 * core/od_image.h - the values of an object dictionary as a byte image:
 * what 1010h "save" writes and what is loaded at start-up (CiA 301
 * §7.5.2.13). Used by the daemon's lines and by the device simulator, so
 * both keep one format. No I/O here: the caller owns the buffer and the
 * file.
 *
 * Format (little-endian): the 8 bytes "COGWOD1\n", then records
 * { u16 index, u8 sub, u32 len, len bytes }.
 *
 * Parts: CO_OD_IMAGE_COMM = 1000h..1FFFh, CO_OD_IMAGE_APP = 2000h..FFFFh.
 * Only values that can change are written: writable or persistent
 * entries, never constants, never 1010h/1011h themselves.
 */
#ifndef COGW_CORE_OD_IMAGE_H
#define COGW_CORE_OD_IMAGE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/od.h"

#define CO_OD_IMAGE_COMM 0x1u
#define CO_OD_IMAGE_APP 0x2u
#define CO_OD_IMAGE_MAGIC_LEN 8u

/* Apply flags */
#define CO_OD_IMAGE_SET_VALUE 0x1u /* the current value */
#define CO_OD_IMAGE_SET_DEFAULT \
	0x2u /* the default, so a reset comm/app
                                      * returns to the saved value */

/* Does this entry belong to the image of these parts? */
bool co_od_image_includes(const co_od_entry *e, unsigned parts);

/* Write the image of `parts` into buf. Returns its length, or -EMSGSIZE
 * if cap is too small. */
long co_od_image_write(const co_od *od, unsigned parts, uint8_t *buf, size_t cap);

/* Apply an image: every record is checked against the dictionary (entry
 * exists and is part of the image, value passes the type/length/limit
 * checks); records that fail are skipped and counted, never trusted. A
 * truncated tail counts as one skipped record. Returns 0, or -EINVAL if
 * the buffer is not an image at all (nothing applied). */
int co_od_image_apply(co_od *od, const uint8_t *buf, size_t len, unsigned flags, unsigned *applied,
		      unsigned *skipped);

#endif /* COGW_CORE_OD_IMAGE_H */
