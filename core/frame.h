/* SPDX-License-Identifier: MIT */
/*
 * core/frame.h - the one frame type that crosses the core's seam.
 *
 * A co_frame is what the line runtime hands to co_node_recv() and what the
 * core hands back through the send callback. It is plain data: no pointers,
 * safe to copy, safe to put into rings between threads.
 *
 * Classic CAN only today (len 0..8). The data array is sized for CAN FD so
 * that adding FD later (CO_FRAME_FD, len up to 64) does not change the ABI of
 * every module that passes frames around.
 */
#ifndef COGW_CORE_FRAME_H
#define COGW_CORE_FRAME_H

#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#define CO_FRAME_MAX_CLASSIC 8u
#define CO_FRAME_MAX_DATA 64u /* CAN FD payload; classic frames use <= 8 */

#define CO_FRAME_SFF_MASK 0x000007FFu /* 11-bit identifier */
#define CO_FRAME_EFF_MASK 0x1FFFFFFFu /* 29-bit identifier */

/* Frame flags (co_frame.flags). */
enum co_frame_flag {
	CO_FRAME_EXT = 1u << 0, /* 29-bit identifier */
	CO_FRAME_RTR = 1u << 1, /* remote transmission request (classic only) */
	CO_FRAME_FD = 1u << 2,  /* reserved: CAN FD frame (len up to 64) */
	CO_FRAME_BRS = 1u << 3, /* reserved: CAN FD bit-rate switch */
};

typedef struct co_frame {
	uint32_t id;   /* 11- or 29-bit identifier, no flag bits in here */
	uint8_t flags; /* enum co_frame_flag */
	uint8_t len;   /* payload length in bytes (DLC for classic frames) */
	uint8_t _pad[2];
	uint8_t data[CO_FRAME_MAX_DATA];
} co_frame;

/* Initialise a classic 11-bit data frame with len bytes, payload zeroed. */
static inline void co_frame_init(co_frame *f, uint32_t id, uint8_t len)
{
	f->id = id;
	f->flags = 0;
	f->len = len;
	f->_pad[0] = f->_pad[1] = 0;
	memset(f->data, 0, CO_FRAME_MAX_CLASSIC);
}

/* True if the frame is well formed for a classic CAN line. */
static inline bool co_frame_is_valid(const co_frame *f)
{
	if (f->flags & CO_FRAME_FD)
		return false; /* not supported yet */
	if (f->len > CO_FRAME_MAX_CLASSIC)
		return false;
	if (f->flags & CO_FRAME_EXT)
		return (f->id & ~CO_FRAME_EFF_MASK) == 0;
	return (f->id & ~CO_FRAME_SFF_MASK) == 0;
}

/* Little-endian helpers for CANopen payloads (CiA 301 is little-endian). */
static inline uint16_t co_get_le16(const uint8_t *p)
{
	return (uint16_t)(p[0] | (p[1] << 8));
}

static inline uint32_t co_get_le32(const uint8_t *p)
{
	return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
	       ((uint32_t)p[3] << 24);
}

static inline void co_put_le16(uint8_t *p, uint16_t v)
{
	p[0] = (uint8_t)v;
	p[1] = (uint8_t)(v >> 8);
}

static inline void co_put_le32(uint8_t *p, uint32_t v)
{
	p[0] = (uint8_t)v;
	p[1] = (uint8_t)(v >> 8);
	p[2] = (uint8_t)(v >> 16);
	p[3] = (uint8_t)(v >> 24);
}

/* n bytes (at most 8, the rest ignored) of a little-endian value: the
 * numeric types of CiA 301 of any width, PDO-mapped values. */
static inline uint64_t co_get_le(const uint8_t *p, uint32_t n)
{
	uint64_t v = 0;

	for (uint32_t i = 0; i < n && i < 8; i++)
		v |= (uint64_t)p[i] << (8 * i);
	return v;
}

static inline void co_put_le(uint8_t *p, uint32_t n, uint64_t v)
{
	for (uint32_t i = 0; i < n && i < 8; i++)
		p[i] = (uint8_t)(v >> (8 * i));
}

/* ---- COB-ID values of the communication objects (1005h, 1012h, 1014h,
 * 1028h, 14xxh/18xxh, 1280h, ...) ----------------------------------------- */
#define CO_COB_EXT 0x20000000u /* bit 29: a 29-bit CAN-ID (CiA 301 §7.5.2) */

/* The CAN-ID and frame flags a COB-ID value names (bit 29: 29-bit, else
 * the 11-bit identifier); the valid and other flag bits are the caller's. */
static inline void co_cob_split(uint32_t cob, uint32_t *id, uint8_t *flags)
{
	if (cob & CO_COB_EXT) {
		*id = cob & CO_FRAME_EFF_MASK;
		*flags = CO_FRAME_EXT;
	} else {
		*id = cob & CO_FRAME_SFF_MASK;
		*flags = 0;
	}
}

/* CiA 301 §7.3.5 (restricted CAN-IDs): 11-bit identifiers no configurable
 * object may use (NMT, the default SYNC/EMCY/TIME range, SDO, LSS, NMT
 * error control). */
static inline bool co_cob_is_restricted(uint32_t id)
{
	return id <= 0x07F || (id >= 0x101 && id <= 0x180) || (id >= 0x581 && id <= 0x5FF) ||
	       (id >= 0x601 && id <= 0x67F) || (id >= 0x6E0 && id <= 0x6FF) ||
	       (id >= 0x701 && id <= 0x7FF);
}

#endif /* COGW_CORE_FRAME_H */
