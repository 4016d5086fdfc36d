/* SPDX-License-Identifier: MIT */
/*
 * core/sdo.h - what SDO server and client share: abort codes, command
 * specifiers, frame layout constants (CiA 301 §7.2.4.3).
 */
#ifndef COGW_CORE_SDO_H
#define COGW_CORE_SDO_H

#include <stdint.h>

#include "core/frame.h"
#include "core/od.h"

/* SDO abort codes (CiA 301 §7.2.4.3.17, plus the CiA 302-7 routing codes
 * this project uses for network indications, see docs/gateway.md). */
typedef enum sdo_abort {
	SDO_OK = 0,
	SDO_AB_TOGGLE = 0x05030000,            /* toggle bit not alternated */
	SDO_AB_TIMEOUT = 0x05040000,           /* SDO protocol timed out */
	SDO_AB_CMD = 0x05040001,               /* command specifier not valid */
	SDO_AB_BLK_SIZE = 0x05040002,          /* invalid block size */
	SDO_AB_SEQ = 0x05040003,               /* invalid sequence number */
	SDO_AB_CRC = 0x05040004,               /* CRC error */
	SDO_AB_NO_MEM = 0x05040005,            /* out of memory */
	SDO_AB_UNSUPP_ACCESS = 0x06010000,     /* unsupported access */
	SDO_AB_WRITE_ONLY = 0x06010001,        /* attempt to read a wo object */
	SDO_AB_READ_ONLY = 0x06010002,         /* attempt to write a ro object */
	SDO_AB_NO_OBJ = 0x06020000,            /* object does not exist */
	SDO_AB_NO_MAP = 0x06040041,            /* object cannot be mapped */
	SDO_AB_MAP_LEN = 0x06040042,           /* mapping exceeds PDO length */
	SDO_AB_PARAM_INCOMPAT = 0x06040043,    /* general parameter incompat. */
	SDO_AB_INTERNAL_INCOMPAT = 0x06040047, /* general internal incompat. */
	SDO_AB_HW = 0x06060000,                /* access failed: hardware error */
	SDO_AB_TYPE_LEN = 0x06070010,          /* type/length mismatch */
	SDO_AB_LEN_HIGH = 0x06070012,          /* length too high */
	SDO_AB_LEN_LOW = 0x06070013,           /* length too low */
	SDO_AB_NO_SUB = 0x06090011,            /* sub-index does not exist */
	SDO_AB_VALUE = 0x06090030,             /* invalid value */
	SDO_AB_VALUE_HIGH = 0x06090031,        /* value too high */
	SDO_AB_VALUE_LOW = 0x06090032,         /* value too low */
	SDO_AB_MAX_LT_MIN = 0x06090036,        /* maximum less than minimum */
	SDO_AB_NO_RESOURCE = 0x060A0023,       /* resource not available: SDO conn. */
	SDO_AB_GENERAL = 0x08000000,           /* general error */
	SDO_AB_STORE = 0x08000020,             /* cannot transfer/store */
	SDO_AB_LOCAL_CTRL = 0x08000021,        /* ... because of local control */
	SDO_AB_DEV_STATE = 0x08000022,         /* ... because of device state */
	SDO_AB_NO_OD = 0x08000023,             /* no object dictionary */
	SDO_AB_NO_DATA = 0x08000024,           /* no data available */
	SDO_AB_NET_UNKNOWN = 0x0A000001,       /* CiA 302-7: network unknown */
	SDO_AB_NODE_UNKNOWN = 0x0A000002,      /* CiA 302-7: node unknown/silent */
	SDO_AB_ROUTE_BUSY = 0x0A000003,        /* CiA 302-7: routing channel busy */
} sdo_abort;

/* "object does not exist", ...; "unknown abort code" for others. */
const char *sdo_abort_to_string(uint32_t code);
/* The one table from a local call's failure (a negative errno, in an SDO
 * transfer: a data source or sink, a hook, the SDO client pool or a relay
 * lease) to the abort code that goes on the wire; 0 stays 0, an errno
 * nobody expects is SDO_AB_STORE (08000020, "cannot be transferred or
 * stored"). */
uint32_t sdo_abort_of_errno(int rc);

/* Transfer modes (client request hint, also reported in events). */
typedef enum sdo_mode {
	SDO_MODE_AUTO = 0,  /* client picks by size and threshold */
	SDO_MODE_EXPEDITED, /* <= 4 bytes in the initiate frame */
	SDO_MODE_SEGMENTED, /* 7 bytes per segment, confirmed each */
	SDO_MODE_BLOCK,     /* up to 127 segments per confirmation */
} sdo_mode;

const char *sdo_mode_to_string(sdo_mode m);

/* ---- frame layout (byte 0 = command specifier) ------------------------- */

/* Client command specifiers (bits 7..5 of byte 0, client -> server). */
enum sdo_ccs {
	SDO_CCS_DN_SEG = 0,  /* download segment */
	SDO_CCS_DN_INIT = 1, /* initiate download */
	SDO_CCS_UP_INIT = 2, /* initiate upload */
	SDO_CCS_UP_SEG = 3,  /* upload segment */
	SDO_CCS_ABORT = 4,   /* abort transfer */
	SDO_CCS_BLK_UP = 5,  /* block upload */
	SDO_CCS_BLK_DN = 6,  /* block download */
};

/* Command specifier 7 (both directions): CiA 302-7 network indication. */
#define SDO_CS_NETWORK 7u

/* Server command specifiers (bits 7..5 of byte 0, server -> client). */
enum sdo_scs {
	SDO_SCS_UP_SEG = 0,  /* upload segment */
	SDO_SCS_DN_SEG = 1,  /* download segment response */
	SDO_SCS_UP_INIT = 2, /* initiate upload response */
	SDO_SCS_DN_INIT = 3, /* initiate download response */
	SDO_SCS_ABORT = 4,   /* abort transfer */
	SDO_SCS_BLK_DN = 5,  /* block download responses */
	SDO_SCS_BLK_UP = 6,  /* block upload responses */
};

/* Sub-commands in bits 1..0 of block frames (cs / ss). */
enum sdo_blk_sub {
	SDO_BLK_INIT = 0,  /* initiate */
	SDO_BLK_END = 1,   /* end */
	SDO_BLK_ACK = 2,   /* block confirmation (ack) */
	SDO_BLK_START = 3, /* start upload (client -> server) */
};

#define SDO_CS(b) ((uint8_t)((b) >> 5))
#define SDO_TOGGLE 0x10u       /* t bit of segment frames */
#define SDO_SEG_LAST 0x01u     /* c bit of segment frames */
#define SDO_EXPEDITED 0x02u    /* e bit of initiate frames */
#define SDO_SIZE_IND 0x01u     /* s bit of initiate frames */
#define SDO_BLK_CRC 0x04u      /* cc / sc bit of block initiate frames */
#define SDO_BLK_SIZE_IND 0x02u /* s bit of block download/upload initiate */
#define SDO_BLK_SEQ_LAST 0x80u /* c bit of a block sub-block segment */

#define SDO_SEG_DATA 7u      /* data bytes per segment */
#define SDO_EXP_DATA 4u      /* data bytes in an expedited frame */
#define SDO_BLK_MAX_SEQ 127u /* largest block size (segments per block) */

/* Default COB-IDs of the first SDO channel (CiA 301 predefined set). */
#define SDO_COB_RX_BASE 0x600u /* client -> server */
#define SDO_COB_TX_BASE 0x580u /* server -> client */

/* COB-ID bits in 1200h..12FFh sub 1/2. */
#define SDO_COB_INVALID 0x80000000u /* bit 31: channel not valid */
#define SDO_COB_DYN 0x40000000u     /* bit 30: dynamically allocated */
#define SDO_COB_EXT CO_COB_EXT      /* bit 29: 29-bit CAN-ID */

/* Object indexes. */
#define SDO_SERVER_PARAM 0x1200u /* .. 127Fh */
#define SDO_CLIENT_PARAM 0x1280u /* .. 12FFh */
#define SDO_MAX_CHANNELS 128u

/* Create the parameter record idx (1200h+n or 1280h+n) unless the index
 * exists: sub 0 = 3 with access sub0_access, sub 1/2 COB-IDs rw and not
 * valid (bit 31) until the manager or a client over SDO assigns them,
 * sub 3 the peer node-id, rw, 0. 0, -EINVAL or -ENOMEM. */
int sdo_param_od_add(co_od *od, uint16_t idx, uint16_t sub0_access);

#endif /* COGW_CORE_SDO_H */
