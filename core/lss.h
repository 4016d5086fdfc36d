/* SPDX-License-Identifier: MIT */
/*
 * core/lss.h - what LSS master and slave share (CiA 305, layer setting
 * services): COB-IDs, command specifiers, error codes, the LSS address,
 * the CiA bit timing table, and the core service that hosts both ends.
 *
 * - Master -> slave frames use 7E5h, slave -> master 7E4h, always 8 bytes
 *   (unused bytes 00, "reserved by CiA"). Command specifiers overlap with
 *   SDO command specifiers (40h is "switch selective vendor" here and
 *   "upload initiate" on 6xxh): dispatch strictly by COB-ID.
 * - A node runs an LSS master (cfg.lss_master, see core/lss_master.h), an
 *   LSS slave (cfg.lss_slave, see core/lss_slave.h), both or neither. Both
 *   ends hang off node->lss (struct co_lss); the one service co_svc_lss
 *   (core/lss_service.c) initialises, ticks and resets them.
 */
#ifndef COGW_CORE_LSS_H
#define COGW_CORE_LSS_H

#include <stdint.h>

#include "core/co.h"

#define LSS_COBID_MASTER 0x7E5u /* master -> slave */
#define LSS_COBID_SLAVE 0x7E4u  /* slave -> master */

#define LSS_NODE_ID_UNCONFIGURED 0xFFu /* no valid node-ID (CiA 305) */
#define LSS_FASTSCAN_CONFIRM \
	0x80u /* BitChecked value: reset the
					* slaves' Fastscan position, every
					* non-configured slave answers */

/* Command specifiers, byte 0 of every LSS frame. */
typedef enum lss_cs {
	LSS_CS_SWITCH_GLOBAL = 0x04,       /* byte 1: lss_state, no answer */
	LSS_CS_CONFIG_NODE_ID = 0x11,      /* byte 1: node-ID; answer EC/spec */
	LSS_CS_CONFIG_BIT_TIMING = 0x13,   /* bytes 1-2: table, index */
	LSS_CS_ACTIVATE_BIT_TIMING = 0x15, /* bytes 1-2: switch delay ms (LE) */
	LSS_CS_STORE = 0x17,               /* answer EC/spec */
	LSS_CS_SWITCH_SEL_VENDOR = 0x40,   /* bytes 1-4: 1018h:1 */
	LSS_CS_SWITCH_SEL_PRODUCT = 0x41,  /* bytes 1-4: 1018h:2 */
	LSS_CS_SWITCH_SEL_REVISION = 0x42, /* bytes 1-4: 1018h:3 */
	LSS_CS_SWITCH_SEL_SERIAL = 0x43,   /* bytes 1-4: 1018h:4 */
	LSS_CS_SWITCH_SEL_RESPONSE = 0x44, /* slave: selected */
	LSS_CS_IDENT_VENDOR = 0x46,        /* identify remote slave: exact */
	LSS_CS_IDENT_PRODUCT = 0x47,       /* exact */
	LSS_CS_IDENT_REVISION_LOW = 0x48,  /* range, bounds included */
	LSS_CS_IDENT_REVISION_HIGH = 0x49,
	LSS_CS_IDENT_SERIAL_LOW = 0x4A,
	LSS_CS_IDENT_SERIAL_HIGH = 0x4B,          /* last frame: matching slaves answer */
	LSS_CS_IDENT_NON_CONFIGURED = 0x4C,       /* identify non-configured slaves */
	LSS_CS_IDENT_SLAVE = 0x4F,                /* slave: "I match" (also Fastscan) */
	LSS_CS_IDENT_NON_CONFIGURED_SLAVE = 0x50, /* slave: "I am unconfigured" */
	LSS_CS_FASTSCAN = 0x51,       /* 1-4 IDNumber, 5 BitChecked, 6 LSSSub, 7 LSSNext */
	LSS_CS_INQUIRE_VENDOR = 0x5A, /* answer bytes 1-4: 1018h:1 */
	LSS_CS_INQUIRE_PRODUCT = 0x5B,
	LSS_CS_INQUIRE_REVISION = 0x5C,
	LSS_CS_INQUIRE_SERIAL = 0x5D,
	LSS_CS_INQUIRE_NODE_ID = 0x5E, /* answer byte 1: active node-ID */
} lss_cs;

/* "switch-global", "fastscan", ...; "?" for other values. */
const char *lss_cs_to_string(uint8_t cs);

/* Slave states (CiA 305); also the mode byte of switch state global. */
typedef enum lss_state {
	LSS_STATE_WAITING = 0,
	LSS_STATE_CONFIGURATION = 1,
} lss_state;

const char *lss_state_to_string(lss_state s);

/* Error codes in the answers to configure node-ID (11h), configure bit
 * timing (13h) and store configuration (17h). Code 1 means something
 * different per service; 0xFF says "see the implementation-specific
 * error byte" (byte 2). */
#define LSS_EC_OK 0x00u
#define LSS_EC_NODE_ID_RANGE 0x01u     /* 11h: node-ID out of range */
#define LSS_EC_BIT_TIMING_UNSUPP 0x01u /* 13h: bit rate not supported */
#define LSS_EC_STORE_UNSUPP 0x01u      /* 17h: store not supported */
#define LSS_EC_STORE_ACCESS 0x02u      /* 17h: storage media access error */
#define LSS_EC_SPECIFIC 0xFFu          /* implementation specific (spec) */

/* Text for an error code in the answer to cs (11h, 13h or 17h). */
const char *lss_error_to_string(uint8_t cs, uint8_t code);

/* The LSS address: 1018h:1..4. The array index is the Fastscan LSSSub. */
enum lss_id_field {
	LSS_ID_VENDOR = 0,
	LSS_ID_PRODUCT = 1,
	LSS_ID_REVISION = 2,
	LSS_ID_SERIAL = 3,
	LSS_ID_COUNT = 4,
};

typedef struct lss_address {
	uint32_t id[LSS_ID_COUNT];
} lss_address;

/* CiA bit timing table (table selector 0): index -> kbit/s; 0 for the
 * reserved index 5 and anything past 8. */
#define LSS_BT_TABLE_CIA 0u
uint16_t lss_bit_rate_kbit(uint8_t index);

/* The service slot node->lss: NULL members when that end is not enabled. */
struct lss_master;
struct lss_slave;
struct co_lss {
	struct lss_master *master;
	struct lss_slave *slave;
};

/* Hook this into the core's service table (core/co.c). It should run
 * before the other services' reset_comm: the slave's reset_comm makes the
 * pending node-ID active (node->node_id), which the others then read. */
extern const co_service co_svc_lss;

#endif /* COGW_CORE_LSS_H */
