/* SPDX-License-Identifier: MIT */
/*
 * SDO block transfer, the part both directions share (CiA 301 §7.2.4.3.9 ..
 * §7.2.4.3.16). The server's block download and the client's block upload
 * receive with struct sdo_blk_rx; the server's block upload and the client's
 * block download send with struct sdo_blk_tx.
 *
 * The CRC (§7.2.4.3.16) covers the data exactly once, in order, whatever
 * the retransmissions: the receiver adds a segment when it accepts it in
 * sequence, except the last one, whose length only the end request tells;
 * the sender adds bytes when they are acknowledged, which is also the
 * point after which it never sends them again.
 */
#include <string.h>

#include "core/crc16.h"
#include "core/frame.h"
#include "core/sdo_block.h"

/* The receiver's frames carry the same command specifier in both
 * directions, and so do the sender's. */
_Static_assert((int)SDO_SCS_BLK_DN == (int)SDO_CCS_BLK_UP, "ack: same cs both ways");
_Static_assert((int)SDO_CCS_BLK_DN == (int)SDO_SCS_BLK_UP, "end: same cs both ways");

/* ---- receiving side ----------------------------------------------------- */

void sdo_blk_rx_start(struct sdo_blk_rx *rx, uint8_t blksize, bool crc_on)
{
	rx->crc = CRC16_CCITT_INIT;
	rx->crc_on = crc_on;
	rx->blksize = blksize;
	rx->seq = 0;
	rx->last_seen = false;
	rx->prev_valid = false;
}

/* A repeated copy of the frame that closed the previous sub-block (CAN
 * can deliver a frame twice when an ACK error hits its last bit). Acking
 * it again would make the sender resend a whole sub-block that we then
 * take for new data. */
bool sdo_blk_rx_is_dup(const struct sdo_blk_rx *rx, const uint8_t d[8])
{
	return rx->prev_valid && rx->seq == 0 && memcmp(d, rx->prev_seg, 8) == 0;
}

/* Segments are only accepted in sequence. A lost or repeated segment is
 * skipped; at the end of the sub-block (seqno == blksize or c = 1, as the
 * sender sees it) the ack names the last good one and the sender resends
 * from there (CiA 301 §7.2.4.3.9). A seqno outside 1..blksize is a protocol
 * error. */
unsigned sdo_blk_rx_segment(struct sdo_blk_rx *rx, const uint8_t d[8])
{
	uint8_t seq = d[0] & 0x7Fu;
	bool last = d[0] & SDO_BLK_SEQ_LAST;
	unsigned act = SDO_BLK_RX_WAIT;

	if (sdo_blk_rx_is_dup(rx, d))
		return SDO_BLK_RX_WAIT;
	if (seq == 0 || seq > rx->blksize)
		return SDO_BLK_RX_BAD_SEQ;
	if (seq == rx->seq + 1) {
		/* The last segment's padding is only known at the end request:
		 * sdo_blk_rx_crc_ok() adds it from prev_seg. */
		if (rx->crc_on && !last)
			rx->crc = crc16_ccitt(rx->crc, &d[1], SDO_SEG_DATA);
		rx->seq = seq;
		rx->last_seen = last;
		if (seq == rx->blksize || last) {
			memcpy(rx->prev_seg, d, 8);
			rx->prev_valid = true;
		}
		act = SDO_BLK_RX_STORE;
	}
	if (seq == rx->blksize || last)
		act |= SDO_BLK_RX_ACK;
	return act;
}

void sdo_blk_rx_ack(struct sdo_blk_rx *rx, uint8_t d[8])
{
	memset(d, 0, 8);
	d[0] = SDO_BLK_ACK_CMD;
	d[1] = rx->seq;
	d[2] = rx->blksize;
	rx->seq = 0;
}

bool sdo_blk_rx_end(const uint8_t d[8], uint32_t *last_len)
{
	if ((d[0] & SDO_BLK_END_MASK) != SDO_BLK_END_CMD)
		return false;
	*last_len = SDO_SEG_DATA - ((d[0] >> 2) & 7u);
	return true;
}

bool sdo_blk_rx_crc_ok(struct sdo_blk_rx *rx, const uint8_t d[8], uint32_t last_len)
{
	if (!rx->crc_on)
		return true;
	rx->crc = crc16_ccitt(rx->crc, &rx->prev_seg[1], last_len);
	return rx->crc == co_get_le16(&d[1]);
}

/* ---- sending side ------------------------------------------------------- */

void sdo_blk_tx_start(struct sdo_blk_tx *tx, uint8_t blksize, bool crc_on)
{
	tx->crc = CRC16_CCITT_INIT;
	tx->crc_on = crc_on;
	tx->blksize = blksize;
	tx->segs = 0;
	tx->last = false;
	tx->bytes = 0;
}

uint8_t sdo_blk_tx_sub_block(struct sdo_blk_tx *tx, uint32_t avail, bool ends_data)
{
	uint32_t cap = (uint32_t)tx->blksize * SDO_SEG_DATA;

	tx->bytes = avail < cap ? avail : cap;
	tx->last = ends_data && tx->bytes == avail;
	tx->segs = tx->bytes == 0 ? 1 : (uint8_t)((tx->bytes + SDO_SEG_DATA - 1) / SDO_SEG_DATA);
	return tx->segs;
}

uint32_t sdo_blk_tx_ack(struct sdo_blk_tx *tx, const uint8_t d[8], const uint8_t *data,
			uint32_t *acked, bool *done)
{
	uint8_t ackseq = d[1];
	uint32_t n;

	if (d[0] != SDO_BLK_ACK_CMD)
		return SDO_AB_CMD;
	if (ackseq > tx->segs)
		return SDO_AB_SEQ;
	if (!sdo_blk_size_valid(d[2]))
		return SDO_AB_BLK_SIZE;
	n = (uint32_t)ackseq * SDO_SEG_DATA;
	if (n > tx->bytes)
		n = tx->bytes;
	if (tx->crc_on && n)
		tx->crc = crc16_ccitt(tx->crc, data, n);
	*acked = n;
	*done = tx->last && ackseq == tx->segs;
	tx->blksize = d[2];
	return 0;
}

void sdo_blk_tx_end(const struct sdo_blk_tx *tx, uint8_t d[8])
{
	uint32_t last_len = tx->bytes - (uint32_t)(tx->segs - 1) * SDO_SEG_DATA;

	memset(d, 0, 8);
	d[0] = (uint8_t)(SDO_BLK_END_CMD | ((SDO_SEG_DATA - last_len) << 2));
	if (tx->crc_on)
		co_put_le16(&d[1], tx->crc);
}
