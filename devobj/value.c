/* SPDX-License-Identifier: MIT */
/*
 * devobj/value.c - device object values in PDO frames (devobj/value.h).
 */
#include "devobj/value.h"

#include <string.h>

#include "core/frame.h"
#include "core/od.h"
#include "core/sdo.h"

static uint64_t low_bits(unsigned bits)
{
	return bits >= 64u ? UINT64_MAX : ((uint64_t)1 << bits) - 1u;
}

/* UNSIGNED8/16/24/32/40/48/56/64 of at least `bits`. */
static uint16_t unsigned_of(unsigned bits)
{
	static const uint16_t by_bytes[9] = { CO_T_UNSIGNED8,  CO_T_UNSIGNED8,  CO_T_UNSIGNED16,
					      CO_T_UNSIGNED24, CO_T_UNSIGNED32, CO_T_UNSIGNED40,
					      CO_T_UNSIGNED48, CO_T_UNSIGNED56, CO_T_UNSIGNED64 };
	unsigned bytes = (bits + 7u) / 8u;
	return by_bytes[bytes > 8u ? 8u : bytes];
}

/* Bytes a value of `type` has when mapped with `bits`. */
static uint32_t value_size(uint16_t type, unsigned bits)
{
	uint32_t size = co_type_size((co_type)type);
	return size ? size : (bits + 7u) / 8u;
}

uint16_t devobj_value_type(const co_pdo_layout_entry *e, uint16_t asked)
{
	uint16_t t = asked ? asked : e->type ? e->type : unsigned_of(e->bits);
	if (!co_type_is_valid((co_type)t))
		return 0;
	/* a fixed-size type narrower than the mapping cannot hold it; a
	 * string or DOMAIN is mapped in whole bytes */
	if (co_type_is_variable((co_type)t))
		return e->bits % 8u ? 0 : t;
	if (t == CO_T_BOOLEAN)
		return t;
	return co_type_size((co_type)t) * 8u >= e->bits ? t : 0;
}

uint8_t devobj_value_extract(const uint8_t frame[8], const co_pdo_layout_entry *e, uint16_t type,
			     uint8_t out[8])
{
	uint64_t v = (co_get_le(frame, 8) >> e->offset) & low_bits(e->bits);
	uint32_t size = value_size(type, e->bits);
	if (size > 8u)
		size = 8u;
	if (type == CO_T_BOOLEAN)
		v = v != 0;
	else if (co_type_is_signed((co_type)type) && e->bits < 64u && (v >> (e->bits - 1u)) & 1u)
		v |= ~low_bits(e->bits); /* sign-extended (CiA 301 §7.1.5) */
	co_put_le(out, size, v);
	return (uint8_t)size;
}

uint32_t devobj_value_insert(uint8_t frame[8], const co_pdo_layout_entry *e, uint16_t type,
			     const uint8_t *data, uint32_t len)
{
	uint32_t size = value_size(type, e->bits);
	if (co_type_is_variable((co_type)type)) {
		if (len > size)
			return SDO_AB_LEN_HIGH;
	} else if (len != size) {
		return len > size ? SDO_AB_LEN_HIGH : SDO_AB_LEN_LOW;
	}
	uint64_t v = len ? co_get_le(data, len > 8u ? 8u : len) : 0;
	uint64_t mask = low_bits(e->bits);
	if (type == CO_T_BOOLEAN) {
		if (v > 1u)
			return SDO_AB_VALUE;
	} else if (co_type_is_signed((co_type)type) && len < 8u) {
		/* the value as int64, then whether the mapped bits carry it */
		if ((v >> (len * 8u - 1u)) & 1u)
			v |= ~low_bits(len * 8u);
	}
	if (co_type_is_signed((co_type)type) && e->bits < 64u) {
		int64_t s = (int64_t)v, lim = (int64_t)1 << (e->bits - 1u);
		if (s < -lim || s >= lim)
			return SDO_AB_VALUE;
	} else if (v & ~mask) {
		return SDO_AB_VALUE;
	}
	uint64_t f = co_get_le(frame, 8);
	f = (f & ~(mask << e->offset)) | ((v & mask) << e->offset);
	co_put_le(frame, 8, f);
	return 0;
}
