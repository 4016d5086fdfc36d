/* SPDX-License-Identifier: MIT */
/*
 * core/emcy.h - emergency object, producer and consumer (CiA 301 §7.2.7,
 * objects 1001h, 1003h, 1014h, 1015h, 1028h).
 *
 * Producer
 * - co_emcy_send() raises an error: the code goes into the active error
 *   list, 1001h becomes the OR of the active errors' register bits (bit 0,
 *   generic error, is set whenever any error is active), the code is pushed
 *   into 1003h (newest at sub 1, sub 0 = count, oldest falls off the end),
 *   and the 8-byte EMCY frame goes out on the COB-ID in 1014h:
 *       [code lo, code hi, 1001h, msef0..msef4]
 * - co_emcy_clear() removes an error. When no error remains, 1001h drops
 *   to 0 and an "error reset" EMCY (code 0000h, register 00h) is sent.
 * - 1015h (UNSIGNED16, 100 us units) is the inhibit time between two EMCY
 *   frames. A frame produced within the inhibit time is queued (bounded,
 *   CO_EMCY_QUEUE_LEN) and sent when the inhibit time has elapsed: it is
 *   delayed, never silently dropped. A full queue gives -ENOBUFS (the
 *   error is still recorded in 1001h/1003h).
 * - No EMCY frame is transmitted in NMT STOPPED or INITIALISING (CiA 301
 *   §7.3.2.2, table 88); such frames are counted in tx_suppressed.
 * - 1014h: bit 31 = producer disabled, bit 29 = 29-bit CAN-ID; an SDO
 *   write of a different valid COB-ID while the current one is valid, a set
 *   bit 30, or a restricted CAN-ID (CiA 301 §7.3.5) is refused with
 *   0x06090030. Without 1014h the producer uses 80h + node-id.
 * - 1003h sub 0 accepts only 0 (clears the history); other values give
 *   0x06090030.
 *
 * Consumer
 * - 1028h sub n holds the COB-ID of node n's EMCY (bit 31 = not consumed).
 *   Each valid sub gets a receiver; SDO writes take effect at once. Every
 *   8-byte frame on such a COB-ID emits CO_EV_EMCY_RX (node n, code,
 *   register, the 5 manufacturer bytes). Other COB-IDs are not listened
 *   to; frames of another length are counted in rx_invalid and ignored.
 *
 * All functions: owning thread only; return 0 or a negative errno.
 */
#ifndef COGW_CORE_EMCY_H
#define COGW_CORE_EMCY_H

#include <stdint.h>

#include "core/co.h"

#define CO_EMCY_QUEUE_LEN 8u   /* frames waiting for the inhibit time */
#define CO_EMCY_ACTIVE_MAX 16u /* distinct active error codes */
#define CO_EMCY_COB_BASE 0x80u

/* Error register bits (1001h, CiA 301 §7.5.2.2). */
enum co_emcy_reg {
	CO_EMCY_REG_GENERIC = 1u << 0,
	CO_EMCY_REG_CURRENT = 1u << 1,
	CO_EMCY_REG_VOLTAGE = 1u << 2,
	CO_EMCY_REG_TEMP = 1u << 3,
	CO_EMCY_REG_COMM = 1u << 4,
	CO_EMCY_REG_PROFILE = 1u << 5,
	CO_EMCY_REG_MANUF = 1u << 7,
};

/* Emergency error codes used by the core (CiA 301 table 21). */
enum co_emcy_code {
	CO_EMCY_NO_ERROR = 0x0000, /* error reset or no error */
	CO_EMCY_GENERIC = 0x1000,
	CO_EMCY_CAN_OVERRUN = 0x8110, /* CAN overrun (objects lost) */
	CO_EMCY_CAN_PASSIVE = 0x8120, /* CAN in error passive mode */
	CO_EMCY_LIFE_GUARD = 0x8130,  /* life guard or heartbeat error */
	CO_EMCY_BUS_OFF_RECOVERED = 0x8140,
	CO_EMCY_CAN_ID_COLLISION = 0x8150,
	CO_EMCY_PDO_LENGTH = 0x8210,      /* PDO not processed: length error */
	CO_EMCY_PDO_LENGTH_HIGH = 0x8220, /* PDO length exceeded */
	CO_EMCY_DAM_MPDO = 0x8230,
	CO_EMCY_SYNC_LENGTH = 0x8240,
	CO_EMCY_RPDO_TIMEOUT = 0x8250,
};

/* "life guard or heartbeat error", ...; "?" for codes the core does not
 * name (the application owns the rest of the code space). */
const char *co_emcy_code_to_string(uint16_t code);

typedef struct co_emcy_stats {
	uint64_t tx;            /* EMCY frames sent */
	uint64_t queued;        /* frames that had to wait for 1015h */
	uint64_t overflow;      /* frames refused: queue full (-ENOBUFS) */
	uint64_t tx_suppressed; /* not sent: NMT STOPPED/INITIALISING or
	                         * producer disabled (1014h bit 31) */
	uint64_t rx;            /* EMCY frames consumed */
	uint64_t rx_invalid;    /* consumed COB-ID, wrong length */
} co_emcy_stats;

extern const co_service co_svc_emcy;

/*
 * Raise an error and produce its EMCY. reg_bits are the 1001h bits this
 * error stands for (CO_EMCY_REG_*; GENERIC is added). msef may be NULL
 * (five zero bytes). code 0000h is refused (-EINVAL): use co_emcy_clear().
 * Raising a code that is already active updates its bits and sends again.
 * Returns 0 (sent or queued), -ENOBUFS (queue full; recorded, not sent),
 * -ENOSPC (active list full; sent, but cannot be cleared individually),
 * -ENODEV if the node has no EMCY service.
 */
int co_emcy_send(co_node *node, uint16_t code, uint8_t reg_bits, const uint8_t msef[5],
		 uint64_t now_us);

/*
 * The error `code` has gone. 1001h is recomputed from the remaining active
 * errors; if none remains, the "error reset" EMCY 0000h goes out (through
 * the same inhibit queue). -ENOENT if the code was not active.
 */
int co_emcy_clear(co_node *node, uint16_t code, uint64_t now_us);

/* Clear every active error (one error-reset EMCY if any was active). */
int co_emcy_clear_all(co_node *node, uint64_t now_us);

/* Current error register (1001h, or the internal copy if 1001h is absent). */
uint8_t co_emcy_error_register(const co_node *node);
/* True if `code` is in the active error list. */
int co_emcy_is_active(const co_node *node, uint16_t code);

const co_emcy_stats *co_emcy_get_stats(const co_node *node);

/*
 * Add the standard EMCY objects to an OD (entries that exist are kept):
 * 1001h (U8 ro, 0), 1003h (ARRAY: sub0 U8 rw, subs 1..history_len U32 ro;
 * history_len 1..254, 0 = no 1003h), 1014h (U32 rw, 80h + node_id),
 * 1015h (U16 rw, 0) and, if consumers > 0, 1028h subs 1..consumers (U32 rw,
 * default 80h + n, i.e. every node's EMCY consumed; bit 31 set when
 * consume_all is 0). Returns 0, -EINVAL, -ENOMEM.
 */
int co_od_add_comm_defaults_emcy(co_od *od, uint8_t node_id, uint8_t history_len, uint8_t consumers,
				 int consume_all);

#endif /* COGW_CORE_EMCY_H */
