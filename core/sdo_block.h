/* SPDX-License-Identifier: MIT */
/*
 * core/sdo_block.h - the sub-block mechanism of SDO block transfer (CiA 301
 * §7.2.4.3.9 .. §7.2.4.3.16), shared by both directions: the server receives
 * with it in a block download and sends with it in a block upload, the
 * client the other way round.
 *
 * These are the rules only: sequence numbers, duplicate detection, the ack
 * and end frames, the CRC. Where the data comes from or goes to, the frame
 * I/O and the state transitions stay with the caller's state machine.
 * No allocation, no I/O; the objects are plain members of a channel.
 */
#ifndef COGW_CORE_SDO_BLOCK_H
#define COGW_CORE_SDO_BLOCK_H

#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "core/sdo.h"

/* The sub-block confirmation (receiver -> sender): 101 xxx 10 in both
 * directions (scs 5 in a download, ccs 5 in an upload). */
#define SDO_BLK_ACK_CMD ((uint8_t)((SDO_SCS_BLK_DN << 5) | SDO_BLK_ACK))
/* The end request (sender -> receiver): 110 nnn x 1 in both directions
 * (ccs 6 in a download, scs 6 in an upload). */
#define SDO_BLK_END_CMD ((uint8_t)((SDO_CCS_BLK_DN << 5) | SDO_BLK_END))
#define SDO_BLK_END_MASK 0xE3u

/* A blksize from an initiate or an ack: 1..127. */
static inline bool sdo_blk_size_valid(uint8_t blksize)
{
	return blksize != 0 && blksize <= SDO_BLK_MAX_SEQ;
}

/* In a sub-block any byte 0 is a segment header except 0x80 (seqno 0 with
 * c = 1), which can only be an abort. */
static inline bool sdo_blk_seg_is_abort(const uint8_t d[8])
{
	return d[0] == (SDO_CCS_ABORT << 5);
}

/* ---- receiving side ----------------------------------------------------- */

struct sdo_blk_rx {
	uint16_t crc; /* over all data accepted so far but the last segment */
	bool crc_on;
	uint8_t blksize; /* segments per sub-block, as we announced it */
	uint8_t seq;     /* last in-sequence seqno of the current sub-block */
	bool last_seen;  /* the segment with c = 1 was accepted */
	bool prev_valid;
	uint8_t prev_seg[8]; /* the segment that closed the last sub-block; once
	                      * last_seen, the last segment of the data */
};

/* What sdo_blk_rx_segment() asks the caller to do (flags). */
enum sdo_blk_rx_act {
	SDO_BLK_RX_WAIT = 0,          /* nothing to store: wait for the next segment */
	SDO_BLK_RX_STORE = 1u << 0,   /* new in-sequence segment: take d[1..7]
	                             * (all 7 are data unless rx->last_seen:
	                             * then the end request tells how many) */
	SDO_BLK_RX_ACK = 1u << 1,     /* sub-block ends: send sdo_blk_rx_ack() */
	SDO_BLK_RX_BAD_SEQ = 1u << 2, /* seqno outside 1..blksize: abort with
	                               * SDO_AB_SEQ */
};

/* A new transfer: no segment seen yet. */
void sdo_blk_rx_start(struct sdo_blk_rx *rx, uint8_t blksize, bool crc_on);

/* Forget the previous sub-block (a new request on the channel). */
static inline void sdo_blk_rx_reset(struct sdo_blk_rx *rx)
{
	rx->prev_valid = false;
}

/* True if d is a second copy of the segment that closed the previous
 * sub-block; such a frame is to be ignored in any state. */
bool sdo_blk_rx_is_dup(const struct sdo_blk_rx *rx, const uint8_t d[8]);

/* One frame received in the sub-block state (not an abort, see
 * sdo_blk_seg_is_abort()); returns enum sdo_blk_rx_act flags. */
unsigned sdo_blk_rx_segment(struct sdo_blk_rx *rx, const uint8_t d[8]);

/* The sub-block confirmation into d[0..7]; starts the next sub-block. */
void sdo_blk_rx_ack(struct sdo_blk_rx *rx, uint8_t d[8]);

/* True if d is an end request; then *last_len = data bytes in the last
 * segment (0..7). */
bool sdo_blk_rx_end(const uint8_t d[8], uint32_t *last_len);

/* CRC check of an end request, after the caller stored last_len bytes of
 * the last segment: true if CRC is off or it matches. */
bool sdo_blk_rx_crc_ok(struct sdo_blk_rx *rx, const uint8_t d[8], uint32_t last_len);

/* ---- sending side ------------------------------------------------------- */

struct sdo_blk_tx {
	uint16_t crc; /* over all data acknowledged so far */
	bool crc_on;
	uint8_t blksize; /* segments per sub-block, as the receiver asks */
	uint8_t segs;    /* segments in the sub-block sent */
	bool last;       /* that sub-block ends the data */
	uint32_t bytes;  /* data bytes in it */
};

/* A new transfer with the receiver's blksize (already validated). */
void sdo_blk_tx_start(struct sdo_blk_tx *tx, uint8_t blksize, bool crc_on);

/* Plan the next sub-block from `avail` bytes at hand (the not yet
 * acknowledged data); ends_data: nothing follows them. Returns the number of
 * segments to send, 1..blksize (one empty segment for no data at all). */
uint8_t sdo_blk_tx_sub_block(struct sdo_blk_tx *tx, uint32_t avail, bool ends_data);

/* Segment seq (1..segs) of the planned sub-block into d[0..7]; data = the
 * first byte of the sub-block. */
static inline void sdo_blk_tx_segment(const struct sdo_blk_tx *tx, uint8_t seq, const uint8_t *data,
				      uint8_t d[8])
{
	uint32_t off = (uint32_t)(seq - 1) * SDO_SEG_DATA;
	uint32_t len = tx->bytes - off < SDO_SEG_DATA ? tx->bytes - off : SDO_SEG_DATA;

	d[0] = (uint8_t)(seq | (tx->last && seq == tx->segs ? SDO_BLK_SEQ_LAST : 0));
	if (len == SDO_SEG_DATA) { /* all but the last: a fixed-size copy */
		memcpy(&d[1], data + off, SDO_SEG_DATA);
		return;
	}
	memcpy(&d[1], data + off, len);
	memset(&d[1 + len], 0, SDO_SEG_DATA - len);
}

/* A sub-block confirmation d for the sub-block starting at data: 0 and
 * *acked = bytes confirmed (they leave the CRC and need not be sent again),
 * *done = all data confirmed (send sdo_blk_tx_end()); or an abort code. */
uint32_t sdo_blk_tx_ack(struct sdo_blk_tx *tx, const uint8_t d[8], const uint8_t *data,
			uint32_t *acked, bool *done);

/* The end request into d[0..7], after the last sub-block was confirmed. */
void sdo_blk_tx_end(const struct sdo_blk_tx *tx, uint8_t d[8]);

#endif /* COGW_CORE_SDO_BLOCK_H */
