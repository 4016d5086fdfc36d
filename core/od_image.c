/* SPDX-License-Identifier: MIT */
#include "core/od_image.h"

#include <errno.h>
#include <string.h>

#include "core/frame.h"
#include "core/store.h"

static const uint8_t image_magic[CO_OD_IMAGE_MAGIC_LEN] = {
	'C', 'O', 'G', 'W', 'O', 'D', '1', '\n'
};

#define RECORD_HEAD 7u

bool co_od_image_includes(const co_od_entry *e, unsigned parts)
{
	if (e->index == CO_STORE_IDX_SAVE || e->index == CO_STORE_IDX_LOAD)
		return false;
	if (!(e->access & (CO_ACC_WRITE | CO_ACC_PERSIST)) || (e->access & CO_ACC_CONST))
		return false;
	if (e->index >= 0x1000 && e->index <= 0x1FFF)
		return parts & CO_OD_IMAGE_COMM;
	return e->index >= 0x2000 && (parts & CO_OD_IMAGE_APP);
}

long co_od_image_write(const co_od *od, unsigned parts, uint8_t *buf, size_t cap)
{
	size_t used = sizeof image_magic;
	if (cap < used)
		return -EMSGSIZE;
	memcpy(buf, image_magic, sizeof image_magic);
	for (size_t i = 0; i < co_od_count(od); i++) {
		const co_od_entry *e = co_od_at(od, i);
		if (!co_od_image_includes(e, parts))
			continue;
		if (cap - used < RECORD_HEAD + (size_t)e->size)
			return -EMSGSIZE;
		uint8_t *p = buf + used;
		co_put_le16(p, e->index);
		p[2] = e->sub;
		co_put_le32(p + 3, e->size);
		memcpy(p + RECORD_HEAD, e->data, e->size);
		used += RECORD_HEAD + e->size;
	}
	return (long)used;
}

int co_od_image_apply(co_od *od, const uint8_t *buf, size_t len, unsigned flags, unsigned *applied,
		      unsigned *skipped)
{
	*applied = *skipped = 0;
	if (len < sizeof image_magic || memcmp(buf, image_magic, sizeof image_magic) != 0)
		return -EINVAL;
	size_t pos = sizeof image_magic;
	while (pos < len) {
		if (len - pos < RECORD_HEAD) {
			(*skipped)++;
			break;
		}
		uint16_t index = co_get_le16(buf + pos);
		uint8_t sub = buf[pos + 2];
		uint32_t n = co_get_le32(buf + pos + 3);
		pos += RECORD_HEAD;
		if (n > len - pos) {
			(*skipped)++;
			break;
		}
		co_od_entry *e = co_od_find(od, index, sub);
		if (!e || !co_od_image_includes(e, CO_OD_IMAGE_COMM | CO_OD_IMAGE_APP) ||
		    co_od_check_value(e, buf + pos, n) != 0) {
			(*skipped)++;
		} else {
			if (flags & CO_OD_IMAGE_SET_DEFAULT)
				co_od_entry_set_default_bytes(e, buf + pos, n);
			if (flags & CO_OD_IMAGE_SET_VALUE)
				co_od_entry_set_bytes(e, buf + pos, n);
			(*applied)++;
		}
		pos += n;
	}
	return 0;
}
