/* SPDX-License-Identifier: MIT */
/*
 * core/store_file.c - integrity trailer and generations of saved parameter
 * files. See the header for the format and why.
 */
#include "core/store_file.h"

#include <errno.h>
#include <string.h>

#include "core/frame.h"

static const uint8_t trailer_magic[8] = { 'C', 'O', 'G', 'W', 'S', 'U', 'M', '1' };

uint32_t co_crc32(uint32_t crc, const void *data, size_t len)
{
	const uint8_t *p = data;

	crc = ~crc;
	while (len--) {
		crc ^= *p++;
		for (int k = 0; k < 8; k++)
			crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
	}
	return ~crc;
}

long co_store_file_seal(uint8_t *buf, size_t image_len, size_t cap, uint32_t generation,
			uint32_t set)
{
	uint8_t *t;

	if (cap < CO_STORE_FILE_TRAILER || image_len > cap - CO_STORE_FILE_TRAILER ||
	    image_len > UINT32_MAX)
		return -EMSGSIZE;
	t = buf + image_len;
	memcpy(t, trailer_magic, sizeof trailer_magic);
	co_put_le32(t + 8, generation);
	co_put_le32(t + 12, set);
	co_put_le32(t + 16, (uint32_t)image_len);
	uint32_t crc = co_crc32(0, buf, image_len);

	crc = co_crc32(crc, t + 8, 12);
	co_put_le32(t + 20, crc);
	return (long)(image_len + CO_STORE_FILE_TRAILER);
}

int co_store_file_check(const uint8_t *buf, size_t len, co_store_file_info *info)
{
	const uint8_t *t;
	uint32_t crc;

	if (len < CO_STORE_FILE_TRAILER)
		return -ENODATA;
	t = buf + len - CO_STORE_FILE_TRAILER;
	if (memcmp(t, trailer_magic, sizeof trailer_magic) != 0)
		return -ENODATA;
	if (co_get_le32(t + 16) != len - CO_STORE_FILE_TRAILER)
		return -EBADMSG;
	crc = co_crc32(0, buf, len - CO_STORE_FILE_TRAILER);
	crc = co_crc32(crc, t + 8, 12);
	if (crc != co_get_le32(t + 20))
		return -EBADMSG;
	info->generation = co_get_le32(t + 8);
	info->set = co_get_le32(t + 12);
	info->image_len = len - CO_STORE_FILE_TRAILER;
	return 0;
}

int co_store_file_torn(const co_store_file_info *info, const int *present, const unsigned *part,
		       size_t n)
{
	size_t newest = n;

	for (size_t i = 0; i < n; i++)
		if (present[i] && (newest == n || info[i].generation > info[newest].generation))
			newest = i;
	if (newest == n)
		return 0; /* nothing saved */
	for (size_t i = 0; i < n; i++) {
		if (i == newest || !(info[newest].set & part[i]))
			continue;
		/* saved together with the newest: must be of its generation */
		if (!present[i] || info[i].generation != info[newest].generation)
			return 1;
	}
	return 0;
}
