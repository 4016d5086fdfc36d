/* SPDX-License-Identifier: MIT */
/*
 * mailbox/proto.h - THE mailbox wire format, shared by the daemon (one
 * mbx_server per line) and the clients (libcogw). docs/mailbox.md is the
 * prose version of this file; keep both in step.
 *
 * Transport: POSIX message queues on one host.
 *   - one command queue per line, created by the daemon:
 *       /cogw.<instance>.line<N>.cmd        (mbx_queue_name())
 *   - per client one response queue and one event queue, created by the
 *     client (mode 0600, O_EXCL) and announced with MBX_CMD_REGISTER on
 *     every line it uses.
 *
 * Every message = one 48-byte header (mbx_hdr, explicit little-endian
 * encoding, mbx_hdr_encode/mbx_hdr_decode) + hdr.len payload bytes.
 *
 * Payloads are fixed-layout structs (below): fixed-width fields, natural
 * alignment, every gap an explicit zero "pad" field, sizes pinned by static
 * asserts. They are copied with memcpy into an aligned local and then
 * validated field by field. This is safe because both ends run on the same
 * host (a message queue never leaves the machine) and the build refuses a
 * big-endian host: the byte order on the wire is little-endian, as the
 * header's. Version 1 = this file; any incompatible change bumps
 * MBX_VERSION, compatible additions use new command/event codes or the
 * reserved/pad fields (which must be zero today, so they can gain meaning).
 *
 * Data larger than one message (domains, big SDO transfers) travels in
 * ordered chunks under one correlation id (MBX_F_CHUNKED, see "Chunking").
 */
#ifndef COGW_MAILBOX_PROTO_H
#define COGW_MAILBOX_PROTO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "mailbox/proto_app.h"
#include "mailbox/proto_appwd.h"
#include "mailbox/proto_health.h"
#include "mailbox/proto_scan.h"

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "mailbox payload structs assume a little-endian host (see proto.h)"
#endif

/* ---- envelope ------------------------------------------------------------ */

#define MBX_MAGIC 0x5743u /* bytes 'C' 'W' */
#define MBX_VERSION 1u
#define MBX_HDR_SIZE 48u

#define MBX_MSG_MIN 256u   /* smallest mq_msgsize any queue may have */
#define MBX_MSG_MAX 65535u /* largest message (hdr.len is 16 bits) */
#define MBX_MSG_DEFAULT 1024u
#define MBX_QNAME_MAX 64u    /* queue name incl. the NUL */
#define MBX_INSTANCE_MAX 32u /* instance name chars */
#define MBX_LINES_MAX 64u    /* line numbers 0..63 */

typedef enum mbx_kind {
	MBX_KIND_COMMAND = 1,  /* client -> daemon */
	MBX_KIND_RESPONSE = 2, /* daemon -> client response queue */
	MBX_KIND_EVENT = 3,    /* daemon -> client event queue */
} mbx_kind;

const char *mbx_kind_to_string(unsigned k);

/* Header flags. */
enum mbx_flag {
	MBX_F_CHUNKED = 1u << 0,  /* part of a chunked transfer (hdr.total) */
	MBX_F_MORE = 1u << 1,     /* more chunks follow (needs CHUNKED) */
	MBX_F_OVERFLOW = 1u << 2, /* daemon -> client: hdr.dropped messages to
	                           * this queue were lost before this one */
	MBX_F_NO_REPLY = 1u << 3, /* command: do not send a response (errors
	                           * are still counted) */
};
#define MBX_F_CMD_MASK (MBX_F_CHUNKED | MBX_F_MORE | MBX_F_NO_REPLY)
#define MBX_F_OUT_MASK (MBX_F_CHUNKED | MBX_F_MORE | MBX_F_OVERFLOW)

/*
 * The header, decoded. Wire layout (little-endian):
 *   0 u16 magic     4 u16 code    7 u8 flags    12 i32 status  24 u64 token
 *   2 u8  version   6 u8  line    8 u32 client  16 u64 corr    32 u32 abort
 *   3 u8  kind                                                  36 u32 dropped
 *   40 u16 chunk    42 u16 len    44 u32 total
 */
typedef struct mbx_hdr {
	uint16_t magic;   /* MBX_MAGIC */
	uint8_t version;  /* MBX_VERSION */
	uint8_t kind;     /* mbx_kind */
	uint16_t code;    /* command code (command, response) or event code */
	uint8_t line;     /* CAN line, 0-based */
	uint8_t flags;    /* enum mbx_flag */
	uint32_t client;  /* id given by REGISTER (0 in REGISTER itself) */
	int32_t status;   /* response: 0 or a negative mbx_status; else 0 */
	uint64_t corr;    /* client-chosen correlation id, echoed */
	uint64_t token;   /* command: session secret from REGISTER; else 0 */
	uint32_t abort;   /* response/event: CiA 301 abort code, 0 = none */
	uint32_t dropped; /* with MBX_F_OVERFLOW: messages lost before this */
	uint16_t chunk;   /* chunked: index 0.. ; else 0 */
	uint16_t len;     /* payload bytes after the header */
	uint32_t total;   /* chunked: total data bytes of the transfer; else 0 */
} mbx_hdr;

/* ---- status: one error space for the daemon and libcogw ------------------ */

typedef enum mbx_status {
	MBX_OK = 0,
	MBX_E_VERSION = -1,        /* unsupported protocol version */
	MBX_E_MALFORMED = -2,      /* a header or payload field is invalid */
	MBX_E_UNKNOWN_CMD = -3,    /* command code not known to this daemon */
	MBX_E_BAD_LINE = -4,       /* line does not match the queue */
	MBX_E_NOT_REGISTERED = -5, /* unknown client id or wrong token */
	MBX_E_ACCESS = -6,         /* access denied (user / queue owner / mode) */
	MBX_E_PARAM = -7,          /* parameter out of range (node, cs, ...) */
	MBX_E_TOO_BIG = -8,        /* data larger than the configured limit */
	MBX_E_BUSY = -9,           /* resource busy, retry later */
	MBX_E_FULL = -10,          /* client table of this line full */
	MBX_E_QUEUE = -11,         /* client queue cannot be opened / unusable */
	MBX_E_TIMEOUT = -12,       /* no answer in time / chunk stream stalled */
	MBX_E_ABORT = -13,         /* SDO or OD access aborted: hdr.abort */
	MBX_E_STATE = -14,         /* not possible in the current state */
	MBX_E_UNSUPPORTED = -15,   /* service not available on this line */
	MBX_E_SEQUENCE = -16,      /* chunk out of order / unexpected chunk */
	MBX_E_OVERFLOW = -17,      /* messages were dropped (queue full) */
	MBX_E_INTERNAL = -18,      /* daemon-side failure */
	MBX_E_SHUTDOWN = -19,      /* line is stopping */
	MBX_E_LSS = -20,           /* LSS slave answered an error (payload) */
	MBX_E_NOT_FOUND = -21,     /* LSS identify/fastscan: nobody answered */
	MBX_E_NO_ANSWER = -22,     /* the device on the bus did not answer a
	                          * confirmed service in time (the daemon did:
	                          * not to be confused with MBX_E_TIMEOUT) */
	MBX_E_NO_MEMORY = -23,     /* the daemon's transfer memory budget
	                          * (mailbox.transfer_memory) is spent: retry */
	MBX_STATUS_MIN = -23,
} mbx_status;

const char *mbx_status_to_string(int status);
/* The one table from a daemon call's result (0 or a negative errno) to the
 * status a mailbox answer carries: 0 stays 0, an errno nobody expects is
 * MBX_E_INTERNAL. */
int mbx_status_of_errno(int rc);

/* Why a message was refused (counted per reason in mbx_server_stats). */
typedef enum mbx_bad {
	MBX_BAD_NONE = 0,
	MBX_BAD_SHORT, /* shorter than the header */
	MBX_BAD_MAGIC,
	MBX_BAD_VERSION,
	MBX_BAD_KIND,     /* not a command */
	MBX_BAD_LEN,      /* hdr.len != bytes received - header */
	MBX_BAD_FLAGS,    /* unknown flag / MORE without CHUNKED */
	MBX_BAD_CHUNK,    /* chunk/total inconsistent */
	MBX_BAD_RESERVED, /* status/abort/dropped not 0 in a command, pads */
	MBX_BAD_LINE,
	MBX_BAD_CMD,      /* unknown command code */
	MBX_BAD_SIZE,     /* payload size wrong for the command */
	MBX_BAD_PARAM,    /* field value out of range */
	MBX_BAD_CLIENT,   /* unknown client id / wrong token */
	MBX_BAD_SEQUENCE, /* chunk does not continue an open transfer */
	MBX_BAD_QUEUE,    /* REGISTER: queue name invalid or queue unusable */
	MBX_BAD_COUNT
} mbx_bad;

const char *mbx_bad_to_string(unsigned b);
/* The status answered for a refusal reason. */
int mbx_bad_status(mbx_bad b);

/* ---- commands ------------------------------------------------------------ */
/*
 * Numbered by family; new commands append inside their family.
 * R = read-type (allowed to read-only users), W = write-type.
 * Payload = request payload; "resp" = response payload (besides the header).
 */
typedef enum mbx_cmd {
	/* 0x00xx protocol: answered by the mailbox server itself */
	MBX_CMD_REGISTER = 0x0001,    /* R mbx_register_req -> mbx_register_resp */
	MBX_CMD_UNREGISTER = 0x0002,  /* R -, resp - */
	MBX_CMD_SUBSCRIBE = 0x0003,   /* R mbx_subscribe_req -> mbx_subscribe_resp */
	MBX_CMD_UNSUBSCRIBE = 0x0004, /* R mbx_unsubscribe_req -> mbx_subscribe_resp */
	MBX_CMD_PING = 0x0005,        /* R -, renews the lease -> mbx_ping_resp */
	MBX_CMD_XFER_ACK = 0x0006,    /* R mbx_xfer_ack, never answered */
	MBX_CMD_MBX_STATS = 0x0007,   /* R - -> mbx_stats_wire */
	/* 0x01xx local object dictionary of the line */
	MBX_CMD_OD_READ = 0x0101,  /* R mbx_obj_req -> data (chunked if large) */
	MBX_CMD_OD_WRITE = 0x0102, /* W mbx_obj_req + data (chunkable) */
	/* 0x02xx remote SDO (client on the line) */
	MBX_CMD_SDO_UPLOAD = 0x0201,   /* R mbx_sdo_req -> data, hdr.abort */
	MBX_CMD_SDO_DOWNLOAD = 0x0202, /* W mbx_sdo_req + data -> -, hdr.abort */
	/* 0x03xx NMT and node table */
	MBX_CMD_NMT = 0x0301,             /* W mbx_nmt_req */
	MBX_CMD_NODE_TABLE = 0x0302,      /* R - -> mbx_node_entry[n] */
	MBX_CMD_NODE_SCAN = 0x0303,       /* W mbx_scan_req -> mbx_scan_resp +
	                                   * mbx_node_ident[n] (proto_scan.h) */
	MBX_CMD_NODE_SCAN_CACHE = 0x0304, /* R - -> the same, from the cache */
	/* 0x04xx PDO / process data */
	MBX_CMD_PDO_REQUEST = 0x0401, /* W mbx_pdo_num_req: send a TPDO now */
	MBX_CMD_PDO_READ = 0x0402,    /* R mbx_obj_req -> data (<= 8 bytes) */
	MBX_CMD_PDO_WRITE = 0x0403,   /* W mbx_obj_req + data (<= 8 bytes) */
	MBX_CMD_RPDO_STATUS = 0x0408, /* R - -> mbx_rpdo_status + mbx_rpdo_fault_entry[n] */
	/* 0x05xx EMCY */
	MBX_CMD_EMCY_SEND = 0x0501, /* W mbx_emcy_req */
	/* 0x06xx raw CAN */
	MBX_CMD_RAW_SEND = 0x0601, /* W mbx_raw_frame[1..MBX_RAW_SEND_MAX] */
	/* 0x07xx LSS master (CiA 305): all W, payload mbx_lss_req,
	 * resp mbx_lss_resp */
	MBX_CMD_LSS_SWITCH_GLOBAL = 0x0701,       /* mode */
	MBX_CMD_LSS_SWITCH_SELECTIVE = 0x0702,    /* vendor product rev_lo ser_lo */
	MBX_CMD_LSS_SET_NODE_ID = 0x0703,         /* node */
	MBX_CMD_LSS_SET_BIT_TIMING = 0x0704,      /* table, bit_index */
	MBX_CMD_LSS_ACTIVATE_BIT_TIMING = 0x0705, /* delay_ms */
	MBX_CMD_LSS_STORE = 0x0706,
	MBX_CMD_LSS_INQUIRE = 0x0707,          /* what -> value */
	MBX_CMD_LSS_IDENTIFY_REMOTE = 0x0708,  /* all ranges -> found */
	MBX_CMD_LSS_IDENTIFY_NONCONF = 0x0709, /* -> found */
	MBX_CMD_LSS_FASTSCAN = 0x070A,         /* timeout_ms -> id[4] */
	/* 0x08xx line status and statistics */
	MBX_CMD_LINE_STATUS = 0x0801,       /* R - -> mbx_line_status */
	MBX_CMD_LINE_HEALTH = 0x0802,       /* R - -> mbx_line_health */
	MBX_CMD_LINE_HEALTH_RESET = 0x0803, /* W -: zero its counters */
	/* 0x09xx store / restore (1010h / 1011h of the line's OD) */
	MBX_CMD_STORE = 0x0901,   /* W mbx_store_req */
	MBX_CMD_RESTORE = 0x0902, /* W mbx_store_req */
	/* 0x0Axx manager (CiA 302-2/-3; answered when the line has one) */
	MBX_CMD_MGR_STATUS = 0x0A01,         /* R - -> mbx_mgr_status */
	MBX_CMD_MGR_BOOT = 0x0A02,           /* W mbx_mgr_node_req: node 0 = the network */
	MBX_CMD_MGR_START = 0x0A03,          /* W -: start the network (1F80h bit 2/3) */
	MBX_CMD_MGR_REQUEST_NMT = 0x0A04,    /* W mbx_mgr_nmt_req (1F82h) */
	MBX_CMD_MGR_NODE_DIAG = 0x0A05,      /* R mbx_mgr_node_req -> mbx_mgr_node_diag */
	MBX_CMD_MGR_RESET_COUNTERS = 0x0A06, /* W - */
	MBX_CMD_MGR_PROGRAM = 0x0A07,        /* W mbx_mgr_program_req + image
	                                      * -> mbx_mgr_program_resp */
	MBX_CMD_MGR_NODE_SET = 0x0A10,       /* W mbx_mgr_node_set_req + concise DCF:
	                                      * a node added, changed or removed
	                                      * at run time */
	/* 0x0Bxx gateway (CiA 302-7, docs/gateway.md) */
	MBX_CMD_GW_ROUTES = 0x0B01,       /* R - -> mbx_gw_status + mbx_gw_route[n] */
	MBX_CMD_GW_SDO_UPLOAD = 0x0B02,   /* R mbx_gw_sdo_req -> data, hdr.abort */
	MBX_CMD_GW_SDO_DOWNLOAD = 0x0B03, /* W mbx_gw_sdo_req + data -> -, hdr.abort */
	/* 0x0Cxx device objects of the line's slaves (docs/devices.md) */
	MBX_CMD_DEV_LAYOUT = 0x0C01,   /* R mbx_dev_node_req -> the learned PDO layouts
	                               * (docs/mailbox.md "Device objects") */
	MBX_CMD_DEV_WATCH = 0x0C02,    /* R mbx_dev_watch_req -> mbx_dev_watch_resp */
	MBX_CMD_DEV_UNWATCH = 0x0C03,  /* R mbx_dev_obj_req -> - */
	MBX_CMD_DEV_READ = 0x0C04,     /* R mbx_dev_read_req -> mbx_dev_value + data */
	MBX_CMD_DEV_WRITE = 0x0C05,    /* W mbx_dev_obj_req + data -> mbx_dev_write_resp */
	MBX_CMD_DEV_FORWARDS = 0x0C06, /* R - -> mbx_dev_forward[n]: this line's ends of
	                                * gateway.forward with their counters */
	/* 0x0Dxx objects a client owns on the line's own node
	 * (mailbox/proto_app.h, docs/application.md) */
	MBX_CMD_APP_CLAIM = 0x0D01,     /* W mbx_app_claim_req + default -> - */
	MBX_CMD_APP_RELEASE = 0x0D02,   /* W mbx_obj_req -> - */
	MBX_CMD_APP_ANSWER = 0x0D03,    /* W mbx_app_answer_req + value (chunkable) -> - */
	MBX_CMD_APP_IND_DATA = 0x0D04,  /* W mbx_app_ind_req -> the write's data */
	MBX_CMD_APP_LIST = 0x0D05,      /* R - -> mbx_app_status + mbx_app_obj[n] */
	MBX_CMD_APP_WATCHDOG = 0x1001,  /* W mbx_appwd_req -> mbx_appwd_resp (proto_appwd.h) */
	MBX_CMD_APP_KEEPALIVE = 0x1002, /* W - -> -: NOT_FOUND undeclared, STATE tripped */
	MBX_CMD_APP_HOLD = 0x1003,      /* W mbx_appwd_hold_req -> mbx_appwd_nmt */
	MBX_CMD_HOST_READY = 0x1004,    /* W mbx_host_ready_req -> - */
	MBX_CMD_APP_STATUS = 0x1005,    /* R - -> mbx_appwd_status + mbx_appwd_entry[n] */
} mbx_cmd;

const char *mbx_cmd_to_string(unsigned code); /* "?" if unknown */

/* Static facts about one command (mbx_cmd_lookup). */
enum mbx_cmd_flag {
	MBX_CI_WRITE = 1u << 0,  /* write-type: refused to read-only users */
	MBX_CI_SERVER = 1u << 1, /* answered by mbx_server itself */
	MBX_CI_DATA = 1u << 2,   /* fixed part + trailing data, chunkable */
	MBX_CI_ARRAY = 1u << 3,  /* payload = n * fixed (n >= 1) */
	MBX_CI_QUIET = 1u << 4,  /* never answered (XFER_ACK) */
};

typedef struct mbx_cmd_info {
	uint16_t code;
	uint8_t flags;     /* enum mbx_cmd_flag */
	uint16_t fixed;    /* fixed payload part (array: element size) */
	uint16_t max_data; /* DATA: max trailing bytes, 0 = any (chunked);
	                    * ARRAY: max elements */
	const char *name;
	/* the fixed part's fields, once its size is right: 0 or a refusal
	 * (mbx_cmd_validate's); NULL = nothing to check */
	int (*check)(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad);
} mbx_cmd_info;

const mbx_cmd_info *mbx_cmd_lookup(unsigned code); /* NULL if unknown */

/* ---- events -------------------------------------------------------------- */

/* Subscription classes (bit mask, per client and per line). */
enum mbx_event_class {
	MBX_EVC_NMT = 1u << 0,       /* NMT state changes of nodes */
	MBX_EVC_HB = 1u << 1,        /* heartbeat / guarding started, lost */
	MBX_EVC_BOOT = 1u << 2,      /* boot-up messages */
	MBX_EVC_EMCY = 1u << 3,      /* EMCY received */
	MBX_EVC_PDO = 1u << 4,       /* RPDO received, with mapped values */
	MBX_EVC_SDO = 1u << 5,       /* SDO transfers of any client completed */
	MBX_EVC_CAN = 1u << 6,       /* CAN controller state (bus-off, ...) */
	MBX_EVC_RAW = 1u << 7,       /* raw frames, opt-in, id/mask filtered */
	MBX_EVC_OD = 1u << 8,        /* local object written over SDO */
	MBX_EVC_MANAGER = 1u << 9,   /* manager state, unexpected/late/lost nodes */
	MBX_EVC_GW = 1u << 10,       /* gateway: routed SDO sessions, EMCYs forwarded */
	MBX_EVC_OVERFLOW = 1u << 31, /* always delivered, cannot be cleared */

	MBX_EVC_SYNC = 1u << 11,      /* SYNC produced or received (up to 1 per ms) */
	MBX_EVC_TIME = 1u << 12,      /* TIME stamp produced or received */
	MBX_EVC_PDO_FAULT = 1u << 13, /* RPDO supervision: deadline, length */
	MBX_EVC_VALUE = 1u << 14,     /* typed values of watched device objects; only
	                               * the objects the client watches (DEV_WATCH) */
	MBX_EVC_APP = 1u << 15,       /* watchdog trips, own NMT, host ready: subscribers;
	                               * indications: their owner, subscribed or not */
};
#define MBX_EVC_ALL 0x0000FFFFu

/* Name of a single class bit ("nmt", "hb", ...); "?" otherwise. */
const char *mbx_event_class_to_string(uint32_t cls);

typedef enum mbx_event {
	MBX_EV_OVERFLOW = 0x0001,   /* mbx_ev_overflow */
	MBX_EV_OD_WRITTEN = 0x0101, /* OD  mbx_ev_od_written */
	MBX_EV_SDO_DONE = 0x0201,   /* SDO mbx_ev_sdo_done */
	MBX_EV_NMT_STATE = 0x0301,  /* NMT mbx_ev_node */
	MBX_EV_BOOTUP = 0x0302,     /* BOOT mbx_ev_node */
	MBX_EV_HB_STARTED = 0x0303, /* HB mbx_ev_node */
	MBX_EV_HB_LOST = 0x0304,    /* HB mbx_ev_node */
	MBX_EV_DUP_NODE = 0x0305,   /* NMT mbx_ev_dup_node */
	MBX_EV_PDO = 0x0401,        /* PDO mbx_ev_pdo + mbx_pdo_value[n] */
	MBX_EV_EMCY = 0x0501,       /* EMCY mbx_ev_emcy */
	MBX_EV_RAW = 0x0601,        /* RAW mbx_ev_raw */
	MBX_EV_CAN_STATE = 0x0801,  /* CAN mbx_ev_can_state */
	MBX_EV_COMM_FAULT = 0x0802, /* CAN mbx_ev_comm_fault (proto_health.h) */
	MBX_EV_MGR_STATE = 0x0A01,  /* MANAGER mbx_ev_mgr: line state/flags */
	MBX_EV_MGR_BOOT = 0x0A02,   /* BOOT mbx_ev_mgr: one boot step of a node */
	MBX_EV_MGR_NODE = 0x0A03,   /* MANAGER mbx_ev_mgr: a node event */
	MBX_EV_GW_SDO = 0x0B01,     /* GW mbx_ev_gw_sdo: a routed session ended */
	MBX_EV_GW_EMCY = 0x0B02,    /* GW mbx_ev_gw_emcy: an EMCY was forwarded */

	MBX_EV_GUARD_TOGGLE = 0x0306,   /* HB mbx_ev_node: toggle bit repeated */
	MBX_EV_LIFE_LOST = 0x0307,      /* HB mbx_ev_node: our node no longer guarded */
	MBX_EV_LIFE_RESUMED = 0x0308,   /* HB mbx_ev_node: guarded again */
	MBX_EV_UNKNOWN_NODE = 0x0309,   /* MANAGER mbx_ev_unknown_node (proto_scan.h) */
	MBX_EV_RPDO_FAULT = 0x0402,     /* PDO_FAULT mbx_ev_rpdo_fault: episode began */
	MBX_EV_RPDO_RECOVERED = 0x0403, /* PDO_FAULT mbx_ev_rpdo_fault: episodes ended */
	MBX_EV_SYNC = 0x0C01,           /* SYNC mbx_ev_sync */
	MBX_EV_TIME = 0x0D01,           /* TIME mbx_ev_time */
	MBX_EV_DEV_VALUE = 0x0E01,      /* VALUE mbx_dev_value + data: a watched object's
	                                 * new value, to its watchers only */
	MBX_EV_DEV_MIRROR = 0x0E02,     /* MANAGER mbx_ev_dev_mirror: a node's mirror
	                                 * PDOs were programmed or released */
	MBX_EV_APP_IND = 0x0F01,        /* APP mbx_ev_app_ind + data: answer with APP_ANSWER */
	MBX_EV_APP_WRITTEN = 0x0F02,    /* APP mbx_ev_app_written + data: a held object */
	MBX_EV_APP_CANCEL = 0x0F03,     /* APP mbx_ev_app_cancel: an indication ended */
	MBX_EV_APP_WD_TIMEOUT = 0x1001, /* APP mbx_ev_appwd: a keep-alive deadline missed */
	MBX_EV_APP_NMT = 0x1002,        /* APP mbx_appwd_nmt: own NMT state, refused start */
	MBX_EV_HOST_STATE = 0x1003,     /* APP mbx_ev_host: host ready / not ready */
} mbx_event;

const char *mbx_event_to_string(unsigned code); /* "?" if unknown */
/* Class bit of an event code, 0 if unknown. */
uint32_t mbx_event_class_of(unsigned code);

/* ---- payloads: protocol ------------------------------------------------- */

typedef struct mbx_register_req {
	uint32_t pid;                   /* the client process, for liveness */
	uint32_t uid;                   /* claimed; must equal the queues' owner */
	uint32_t reserved;              /* 0 */
	char resp_queue[MBX_QNAME_MAX]; /* "/name", NUL-terminated, padded */
	char event_queue[MBX_QNAME_MAX];
} mbx_register_req;

enum mbx_access {
	MBX_ACCESS_NONE = 0,
	MBX_ACCESS_READ = 1,
	MBX_ACCESS_WRITE = 2,
};
const char *mbx_access_to_string(unsigned a);

typedef struct mbx_register_resp {
	uint64_t token;        /* put it in hdr.token of every command */
	uint32_t client;       /* put it in hdr.client of every command */
	uint32_t lease_ms;     /* renew (any command, PING) within; 0 = none */
	uint32_t max_msg;      /* largest command message this line takes */
	uint32_t max_transfer; /* largest chunked data in either direction */
	uint8_t access;        /* enum mbx_access granted */
	uint8_t line;
	uint16_t pad;
	uint32_t pad2;
} mbx_register_resp;

#define MBX_RAW_FILTERS_MAX 4u
#define MBX_RAW_EXT (1u << 31) /* raw id/mask: 29-bit frame */
#define MBX_RAW_RTR (1u << 30) /* raw id/mask: RTR frame */

/* A frame matches if ((frame_id | flags) ^ id) & mask == 0, with the
 * MBX_RAW_EXT / MBX_RAW_RTR bits standing for the frame's flags. */
typedef struct mbx_raw_filter {
	uint32_t id;
	uint32_t mask;
} mbx_raw_filter;

typedef struct mbx_subscribe_req {
	uint32_t classes;  /* MBX_EVC_* to add */
	uint8_t n_filters; /* with MBX_EVC_RAW: 0 = every frame, else
	                      * replaces the raw filters; 0 otherwise */
	uint8_t pad[3];
	mbx_raw_filter filters[MBX_RAW_FILTERS_MAX];
} mbx_subscribe_req;

typedef struct mbx_unsubscribe_req {
	uint32_t classes; /* MBX_EVC_* to remove */
} mbx_unsubscribe_req;

typedef struct mbx_subscribe_resp {
	uint32_t classes; /* active classes after the command */
} mbx_subscribe_resp;

typedef struct mbx_ping_resp {
	uint32_t lease_ms;
	uint32_t pad;
	uint64_t now_us; /* daemon monotonic clock */
} mbx_ping_resp;

/* Flow control of a chunked response: "I have consumed every chunk below
 * next_chunk of transfer hdr.corr". */
typedef struct mbx_xfer_ack {
	uint16_t next_chunk;
	uint16_t pad;
} mbx_xfer_ack;

/* Mailbox counters of one line (MBX_CMD_MBX_STATS). */
typedef struct mbx_stats_wire {
	uint64_t commands_ok;
	uint64_t malformed; /* sum over reasons */
	uint64_t access_denied;
	uint64_t events_sent;
	uint64_t responses_sent;
	uint64_t dropped;
	uint64_t clients_registered;
	uint64_t clients_reaped;
	uint32_t clients; /* current */
	uint32_t pad;
	/* Added in wire version 1's second revision (an older daemon's answer ends before them:
	 * libcogw leaves them 0). */
	uint64_t xfer_failed;    /* chunked transfers refused or ended early */
	uint64_t xfer_expired;   /*   of which: stalled or over their lifetime */
	uint64_t limited;        /* refused by a per-user/per-client limit */
	uint64_t budget_refused; /* refused by the memory budget, all lines */
	uint64_t budget_used;    /* transfer memory in use now, all lines */
	/* Added later still (an older daemon's answer ends before it). */
	uint64_t late_wakes; /* line woke too late to judge client leases */
	/* Added later still (an older daemon's answer ends before them). */
	uint64_t reg_refused;    /* REGISTERs refused, for any reason */
	uint64_t reg_unanswered; /*   and REGISTERs not answered: their sender may not
				  *   own the queues they name (docs/mailbox.md) */
} mbx_stats_wire;

/* ---- payloads: services ------------------------------------------------- */

/* OD_READ, OD_WRITE (+ data), PDO_READ, PDO_WRITE (+ 1..8 bytes). */
typedef struct mbx_obj_req {
	uint16_t index;
	uint8_t sub;
	uint8_t flags; /* PDO_WRITE: MBX_PDO_TRIGGER; else 0 */
} mbx_obj_req;
#define MBX_PDO_TRIGGER 0x01u /* send event-driven TPDOs mapping it now */

typedef struct mbx_sdo_req {
	uint8_t node; /* 1..127 */
	uint8_t mode; /* 0 auto, 1 expedited, 2 segmented, 3 block */
	uint16_t index;
	uint8_t sub;
	uint8_t pad[3];
	uint32_t timeout_ms; /* per SDO frame; 0 = line default */
	uint32_t size;       /* upload: expected size hint (0 = unknown) */
} mbx_sdo_req;
#define MBX_SDO_MODE_MAX 3u

/* MBX_CMD_GW_SDO_*: an SDO transfer with a node of any network the line's
 * routing table (1F2Ch) reaches; net = the line's own network is a plain
 * transfer on the line. Refusals come as SDO aborts (0A000001 no route,
 * 0A000002 no answer, 060A0023 no client free, ...). */
typedef struct mbx_gw_sdo_req {
	uint16_t net; /* 1..127 */
	uint16_t pad;
	mbx_sdo_req sdo; /* node, index, sub, mode, timeout, size as for SDO */
} mbx_gw_sdo_req;

/* MBX_EV_GW_SDO, on the line the request entered (routed by the SDO server
 * of that line after a network indication). */
typedef struct mbx_ev_gw_sdo {
	uint16_t net;        /* the network asked for */
	uint8_t node;        /* the node asked for */
	uint8_t outcome;     /* 0 routed, 1 aborted, 2 timed out, 3 refused */
	uint32_t abort;      /* 0 or the abort code that ended it */
	uint8_t target_line; /* the line it went out on (0xFF: refused before) */
	uint8_t router;      /* next router's node-ID, 0 = attached */
	uint8_t channel;     /* SDO server channel */
	uint8_t pad;
	uint32_t frames; /* frames relayed (both directions) */
} mbx_ev_gw_sdo;

/* MBX_EV_GW_EMCY, on the line that consumed it. */
typedef struct mbx_ev_gw_emcy {
	uint16_t src_net;
	uint8_t src_node;
	uint8_t pad;
	uint16_t code;  /* the original error code */
	uint16_t lines; /* bit L: handed to line L */
} mbx_ev_gw_emcy;

/* MBX_CMD_GW_ROUTES: the line's gateway counters, then one mbx_gw_route
 * per network with a route or any counted traffic (status.routes), then
 * one mbx_gw_session per routed session running (status.active). */
/* ---- payloads: CiA 302-2 manager (docs/mailbox.md) ------------------------ */

typedef struct mbx_mgr_node_req {
	uint8_t node; /* 1..127 (BOOT: 0 = the whole network) */
	uint8_t pad[3];
} mbx_mgr_node_req;

typedef struct mbx_mgr_nmt_req {
	uint8_t node; /* 1..127, 128 = all nodes */
	uint8_t cmd;  /* 1F82h value: 4 stop, 5 start, 6 reset node,
	                 * 7 reset communication, 127 pre-operational */
	uint16_t pad;
} mbx_mgr_nmt_req;

/* Bit n of word n / 32 = node n. */
typedef struct mbx_mgr_bits {
	uint32_t w[4];
} mbx_mgr_bits;

typedef struct mbx_mgr_status {
	uint8_t state;             /* co_mgr_state (core/manager.h) */
	uint8_t flags;             /* CO_MGR_F_* */
	uint8_t first_error_node;  /* 0 = none */
	char first_error_status;   /* boot status letter, 0 = an EMCY */
	uint32_t first_error_code; /* EMCY code or SDO abort code */
	uint32_t nmt_ignored, unexpected, duplicates, errctrl_events;
	uint32_t keep_op_restarts, network_boots;
	mbx_mgr_bits assigned, present, booted, operational, stopped, preop, mismatch, errctrl_lost,
		emcy_active;
	uint32_t node_changes;         /* MGR_NODE_SET and reloads applied */
	uint32_t node_changes_refused; /* ... refused by the line (status != 0) */
} mbx_mgr_status;

typedef struct mbx_mgr_emcy {
	uint64_t time_us; /* daemon's monotonic clock */
	uint16_t code;
	uint8_t reg;
	uint8_t msef[5];
} mbx_mgr_emcy;

#define MBX_MGR_EMCY_MAX 8
typedef struct mbx_mgr_node_diag {
	uint8_t node;
	uint8_t step;   /* co_mgr_step of the last boot event */
	char status;    /* CiA 302-2 letter of the last failure, 0 = none */
	uint8_t booted; /* 1 = booted */
	uint8_t booting;
	uint8_t nmt_state; /* 1F82h read value (0 unknown, 1 missing, ...) */
	uint8_t sub;       /* object of the last failure */
	uint8_t n_emcy;    /* entries in emcy[], oldest first */
	uint16_t index;
	uint16_t pad;
	uint32_t assignment; /* 1F81h:n */
	uint32_t abort;      /* SDO abort code of the last failure */
	uint32_t value;      /* value read at that failure */
	uint32_t boot_count, fail_count;
	uint32_t own_id_frames; /* node = the line's own node-ID: EMCYs, SDO
	                         * answers and malformed error-control frames
	                         * seen on its identities; 0 for other nodes */
	uint64_t boot_time_us;  /* duration of the last boot */
	mbx_mgr_emcy emcy[MBX_MGR_EMCY_MAX];
} mbx_mgr_node_diag;

/* MBX_CMD_MGR_PROGRAM: a manual program update of one node by the line's
 * CiA 302-3 software manager (core/swmgr.h: stop 1F51h, clear, block
 * download of the image that follows this fixed part to 1F50h:1, start,
 * verify 1F56h:1). The image: 1 byte up to the line's max_transfer,
 * chunked as any data. While it runs, MGR_NODE events "program" (value =
 * bytes sent, expected = image size) carry the request's corr. */
#define MBX_PROGRAM_SDO_TIMEOUT_MAX 60000u
typedef struct mbx_mgr_program_req {
	uint8_t node; /* 1..127, not the line's own node-ID */
	uint8_t pad[3];
	uint32_t expected;       /* 1F56h:1 after the start; 0 = 1F55h:node
	                          * (nothing compared when that is 0 too) */
	uint32_t sdo_timeout_ms; /* per SDO frame; 0 = the manager's */
} mbx_mgr_program_req;

/* The answer (status 0) once the update ran to its end: */
typedef struct mbx_mgr_program_resp {
	char status;    /* 0 = updated and verified; 'I' failed (core/swmgr.h) */
	uint8_t step;   /* co_swmgr_state of the failure (0 = none) */
	uint16_t index; /* object of the failure (0 = none) */
	uint8_t sub;
	uint8_t mode; /* sdo_mode the image went by (block, or segmented after
	               * the device refused block); 0 = not sent */
	uint8_t pad[2];
	uint32_t abort;    /* SDO abort code (0 = none: a wrong 1F56h:1) */
	uint32_t found;    /* 1F56h:1 read after the start */
	uint32_t expected; /* what it was compared with (0 = nothing) */
	uint32_t bytes;    /* image bytes sent */
} mbx_mgr_program_resp;

/* MBX_CMD_MGR_NODE_SET: a slave added to the manager's network list,
 * changed, or removed, without restarting the line (docs/config.md "Nodes
 * at run time"). Add and change write 1F84h..1F88h:n, 1F22h:n (the concise
 * DCF that follows this fixed part; none = an empty 1F22h:n), the 1016h
 * consumer entry of the node, then 1F81h:n, and run the node's boot slave
 * process; remove withdraws 1F81h:n, the 1016h entry and 1F22h:n. Refused:
 * PARAM (the line's own node-ID, a concise DCF that is not one, a
 * heartbeat and a guard time together), TOO_BIG (the DCF does not fit
 * 1F22h:n), STATE (the network boot runs, the manager is in slave mode,
 * or ADD names a node that is assigned already: a duplicate), NOT_FOUND
 * (CHANGE or REMOVE of a node that is not assigned). Refusals are counted
 * (mbx_mgr_status.node_changes_refused). */
enum mbx_node_op {
	MBX_NODE_ADD = 1,    /* refused when 1F81h:n bit 0 is set */
	MBX_NODE_CHANGE = 2, /* refused when it is not */
	MBX_NODE_REMOVE = 3, /* refused when it is not; fields below ignored */
};
#define MBX_NODE_F_KEEP_OP 0x01u /* restart it when it leaves OPERATIONAL */
#define MBX_NODE_F_STORE 0x02u   /* 1010h:1 "save" after a download */
#define MBX_NODE_F_ALL (MBX_NODE_F_KEEP_OP | MBX_NODE_F_STORE)
typedef struct mbx_mgr_node_set_req {
	uint8_t node;         /* 1..127, not the line's own node-ID */
	uint8_t op;           /* enum mbx_node_op */
	uint8_t flags;        /* MBX_NODE_F_* */
	uint8_t target_state; /* after its boot: 5 operational (0 = 5), 127
	                        * pre-operational, 4 stopped (core/nmt.h) */
	uint8_t pdo;          /* 0 off, 1 learn, 2 auto (docs/config.md "pdo") */
	uint8_t pad;
	uint16_t heartbeat_ms; /* its 1016h consumer time, 0 = none */
	uint32_t assignment;   /* 1F81h:n: bit 0 set (add, change) */
	uint32_t identity[5];  /* 1F84h..1F88h:n, 0 = not checked */
	uint32_t date, time;   /* 1F26h:n/1F27h:n, the configuration's date and
	                        * time (CiA 302-3: both 0 = always download) */
} mbx_mgr_node_set_req;

/* MBX_EV_MGR_*: the fields of co_ev_mgr (core/event.h). */
typedef struct mbx_ev_mgr {
	uint8_t node, state, prev, flags;
	uint8_t step;
	char status;
	uint8_t what;
	uint8_t mandatory;
	uint16_t index;
	uint8_t sub;
	uint8_t done;
	uint32_t abort, value, expected;
} mbx_ev_mgr;

typedef struct mbx_gw_status {
	uint16_t network_id; /* this line's network */
	uint8_t routes;      /* mbx_gw_route entries that follow */
	uint8_t active;      /* routed sessions running now: the
	                      * mbx_gw_session entries after the routes */
	uint16_t leases;     /* SDO clients of this line lent to routed
	                      * sessions of other lines now */
	uint16_t pad;
	uint64_t sessions, routed, aborted, timed_out, refused;
	uint64_t relayed_frames; /* frames through this line's relay leases */
	uint64_t pdo_published, pdo_forwarded, pdo_dropped, pdo_applied, pdo_triggered;
	uint64_t emcy_consumed, emcy_forwarded, emcy_unroutable, emcy_dropped, emcy_sent;
	uint64_t ring_drops;
	uint64_t pdo_fast;   /* TPDO frames of other lines this line sent itself
	                    * (docs/gateway.md, one wake-up per hop) */
	uint64_t sdo_across; /* frames of routed SDO transfers this line sent
	                      * on another line's interface (docs/gateway.md) */
} mbx_gw_status;

typedef struct mbx_gw_route {
	uint8_t net;
	uint8_t kind; /* 0 none, 1 attached to `line`, 2 through `router` */
	uint8_t line;
	uint8_t router;
	uint32_t raw; /* the 1F2Ch value */
	uint64_t routed, aborted, timed_out, refused;
} mbx_gw_route;

/* One routed SDO session running on the line (entered on its SDO server). */
typedef struct mbx_gw_session {
	uint8_t channel;     /* SDO server channel (0-based) */
	uint8_t target_line; /* line it was routed to, 0xFF = not yet */
	uint8_t router;      /* next router's node-ID, 0 = network attached */
	uint8_t node;        /* target node */
	uint16_t net;        /* target network */
	uint16_t pad;
	uint32_t age_ms; /* since the network indication */
	uint32_t frames; /* relayed so far, both ways */
	char state[32];  /* where the transfer stands ("wait initiate",
	                      * "block upload sub-block", ...), NUL-terminated */
} mbx_gw_session;

typedef struct mbx_nmt_req {
	uint8_t cs;   /* 0x01 start, 0x02 stop, 0x80 pre-op, 0x81 reset node,
	               * 0x82 reset communication (CiA 301 §7.2.8.3.1) */
	uint8_t node; /* 0 = all, 1..127 */
	uint16_t pad;
} mbx_nmt_req;

typedef struct mbx_node_entry {
	uint8_t node;
	uint8_t nmt_state;      /* CiA 301 NMT state byte (0 boot, 4 stopped,
	                    * 5 operational, 127 pre-op), 0xFF unknown */
	uint8_t hb;             /* 0 not monitored, 1 active, 2 lost, 3 monitored
	                    * but no heartbeat yet (or since its boot-up) */
	uint8_t flags;          /* bit0 boot-up seen, bit1 EMCY active,
	                         * bit2 two devices answered on this node-ID */
	uint32_t last_heard_ms; /* since its last heartbeat/boot-up frame;
	                         * 0xFFFFFFFF = never heard */
	uint16_t bootups;       /* boot-up messages seen (saturating) */
	uint16_t last_emcy;     /* error code of its last EMCY, 0 = none */
	uint32_t emcy_count;    /* EMCY messages received from it */
} mbx_node_entry;

typedef struct mbx_pdo_num_req {
	uint16_t pdo; /* TPDO number 1..512 */
	uint16_t pad;
} mbx_pdo_num_req;

typedef struct mbx_emcy_req {
	uint16_t code; /* error code; 0 = error reset */
	uint8_t reg;   /* error register 1001h bits */
	uint8_t msef[5];
} mbx_emcy_req;

typedef struct mbx_raw_frame {
	uint32_t id; /* 11- or 29-bit id | MBX_RAW_EXT | MBX_RAW_RTR */
	uint8_t len; /* 0..8 */
	uint8_t pad[3];
	uint8_t data[8];
} mbx_raw_frame;
#define MBX_RAW_SEND_MAX 32u

typedef struct mbx_lss_req {
	uint8_t mode;      /* SWITCH_GLOBAL: 0 waiting, 1 configuration */
	uint8_t node;      /* SET_NODE_ID: 1..127 or 255 (unconfigured) */
	uint8_t table;     /* SET_BIT_TIMING */
	uint8_t bit_index; /* SET_BIT_TIMING */
	uint16_t delay_ms; /* ACTIVATE_BIT_TIMING */
	uint8_t what;      /* INQUIRE: 0x5A vendor .. 0x5D serial, 0x5E node */
	uint8_t pad;
	uint32_t timeout_ms; /* per LSS answer; 0 = line default */
	uint32_t vendor, product, rev_lo, rev_hi, ser_lo, ser_hi;
} mbx_lss_req;

typedef struct mbx_lss_resp {
	uint8_t error;      /* slave error code (MBX_E_LSS) */
	uint8_t spec_error; /* with error 255 */
	uint8_t found;      /* IDENTIFY / FASTSCAN: 1 = a slave answered */
	uint8_t pad;
	uint32_t value; /* INQUIRE */
	uint32_t id[4]; /* FASTSCAN: vendor, product, revision, serial */
} mbx_lss_resp;

enum mbx_can_state {
	MBX_CAN_ACTIVE = 0,
	MBX_CAN_WARNING = 1,
	MBX_CAN_PASSIVE = 2,
	MBX_CAN_BUS_OFF = 3,
	MBX_CAN_STOPPED = 4,
};
const char *mbx_can_state_to_string(unsigned s);

typedef struct mbx_line_status {
	uint8_t can_state; /* enum mbx_can_state */
	uint8_t nmt_state; /* own NMT state */
	uint8_t node_id;   /* own node-id */
	uint8_t pad;
	uint32_t bitrate; /* bit/s, 0 = unknown */
	uint64_t rx_frames, tx_frames, rx_dropped, tx_failed, err_frames, bus_off_count;
	uint32_t clients;           /* mailbox clients on this line */
	uint32_t bus_load_permille; /* bits on the wire in the last full second,
	                             * per mille of the configured bit rate */
} mbx_line_status;

typedef struct mbx_store_req {
	uint8_t sub; /* 1 all, 2 communication, 3 application, 4..127 */
	uint8_t pad[3];
} mbx_store_req;

/* ---- payloads: events --------------------------------------------------- */

typedef struct mbx_ev_overflow {
	uint32_t dropped_events;    /* lost on the event queue since the last
	                             * notice */
	uint32_t dropped_responses; /* lost on the response queue */
} mbx_ev_overflow;

typedef struct mbx_ev_od_written {
	uint16_t index;
	uint8_t sub;
	uint8_t pad;
	uint32_t size;
} mbx_ev_od_written;

/* An SDO transfer of some client ended (observers of the sdo class, e.g.
 * a logger). The requester itself gets the outcome, with the data, as the
 * response to its request. (client, corr in the header) name the request
 * uniquely; correlation ids alone are per client. */
typedef struct mbx_ev_sdo_done {
	uint32_t abort; /* 0 = success */
	uint32_t size;  /* bytes transferred */
	uint16_t index;
	uint8_t sub;
	uint8_t node;
	uint8_t upload; /* 1 upload, 0 download */
	uint8_t mode;   /* mode used */
	uint8_t pad[2];
	uint32_t client; /* the requesting client's id on this line */
	uint32_t pad2;
} mbx_ev_sdo_done;

/* NMT_STATE, BOOTUP, HB_STARTED, HB_LOST */
typedef struct mbx_ev_node {
	uint8_t node;
	uint8_t state; /* NMT state byte (as mbx_node_entry) */
	uint8_t prev;  /* NMT_STATE: previous state */
	uint8_t pad;
} mbx_ev_node;

/* DUP_NODE: two answers came to one SDO request of the line's client: two
 * devices answer on this node-ID (any line, with or without a manager). */
typedef struct mbx_ev_dup_node {
	uint8_t node;
	uint8_t sub; /* the object the request named */
	uint16_t index;
	uint32_t count; /* second answers from this node-ID so far */
	uint32_t abort; /* the second answer's abort code, 0 = none */
} mbx_ev_dup_node;

typedef struct mbx_pdo_value {
	uint16_t index;
	uint8_t sub;
	uint8_t len; /* 1..8 bytes used of data */
	uint8_t data[8];
} mbx_pdo_value;
#define MBX_PDO_VALUES_MAX 64u

typedef struct mbx_ev_pdo {
	uint64_t ts_us;
	uint16_t pdo; /* RPDO number 1..512 */
	uint8_t n;    /* mbx_pdo_value entries that follow */
	uint8_t pad[5];
} mbx_ev_pdo;

typedef struct mbx_ev_emcy {
	uint64_t ts_us;
	uint16_t code;
	uint8_t node;
	uint8_t reg;
	uint8_t msef[5];
	uint8_t pad[7];
} mbx_ev_emcy;

typedef struct mbx_ev_raw {
	uint64_t ts_us;
	mbx_raw_frame frame;
} mbx_ev_raw;

typedef struct mbx_ev_can_state {
	uint8_t state; /* enum mbx_can_state */
	uint8_t prev;
	uint8_t tec; /* transmit error counter, if known */
	uint8_t rec; /* receive error counter, if known */
} mbx_ev_can_state;

/* RPDO supervision faults of the line's own node (CiA 301 §7.5.2.35/36),
 * one bit each. */
enum mbx_rpdo_fault {
	MBX_RPDO_FAULT_TIMEOUT = 1u << 0, /* deadline (1400h+n-1:5) missed: EMCY 8250h */
	MBX_RPDO_FAULT_SHORT = 1u << 1,   /* shorter than mapped, not used: 8210h */
	MBX_RPDO_FAULT_LONG = 1u << 2,    /* longer than mapped, leading bytes used: 8220h */
};
#define MBX_RPDO_FAULT_ALL 0x07u

/* RPDO_FAULT: an episode began (one event, however many bad frames
 * follow); RPDO_RECOVERED: a frame of the mapped length (or the RPDO's
 * reconfiguration, len 0) ended the episodes in `fault`. */
typedef struct mbx_ev_rpdo_fault {
	uint64_t ts_us;
	uint32_t cob_id; /* CAN-ID; bit 29 = 29-bit (as in 1400h:1) */
	uint16_t pdo;    /* RPDO number 1..512 */
	uint8_t fault;   /* MBX_RPDO_FAULT_*: begun (one bit) or ended */
	uint8_t len;     /* bytes received; 0 for a missed deadline */
	uint8_t mapped_len;
	uint8_t pad;
	uint16_t event_ms; /* the deadline in force, 0 = none */
	uint16_t emcy;     /* RPDO_FAULT: the EMCY code our node produced */
	uint16_t pad2;
} mbx_ev_rpdo_fault;

/* SYNC: produced by this line's node or received. */
typedef struct mbx_ev_sync {
	uint64_t ts_us;
	uint8_t counter;  /* 1..1019h, 0 = the SYNC carries none */
	uint8_t produced; /* 1 = our node sent it */
	uint8_t pad[6];
} mbx_ev_sync;

/* TIME: TIME_OF_DAY produced by this line's node or received. */
typedef struct mbx_ev_time {
	uint64_t ts_us;
	int64_t unix_ms;  /* the same instant, ms since 1970-01-01 UTC */
	uint32_t ms;      /* ms after midnight */
	uint16_t days;    /* days since 1984-01-01 */
	uint8_t produced; /* 1 = our node sent it */
	uint8_t pad;
} mbx_ev_time;

/* RPDO_STATUS: the line's RPDO supervision, then one mbx_rpdo_fault_entry
 * per RPDO with an episode open. */
typedef struct mbx_rpdo_status {
	uint64_t rx;          /* RPDO frames used */
	uint64_t rx_length;   /* frames of the wrong length */
	uint64_t rx_timeout;  /* deadlines missed */
	uint64_t rx_late;     /* synchronous RPDOs after the SYNC window */
	uint64_t od_refused;  /* mapped values the OD refused */
	uint32_t episodes[3]; /* begun since start: deadline, short, long */
	uint16_t rpdos;       /* RPDOs the node has */
	uint16_t n;           /* entries that follow */
} mbx_rpdo_status;

typedef struct mbx_rpdo_fault_entry {
	uint32_t cob_id;
	uint16_t pdo;
	uint8_t faults; /* MBX_RPDO_FAULT_* open */
	uint8_t mapped_len;
	uint16_t event_ms;
	uint16_t pad;
} mbx_rpdo_fault_entry;

/* ---- device objects (docs/devices.md) ------------------------------------ */

/* CiA 301 basic data types as the wire carries them (the data type index,
 * CiA 301 §7.4.7.1 table 44; the same numbers as core/od.h co_type). */
enum mbx_data_type {
	MBX_T_BOOLEAN = 0x01,
	MBX_T_INTEGER8 = 0x02,
	MBX_T_INTEGER16 = 0x03,
	MBX_T_INTEGER32 = 0x04,
	MBX_T_UNSIGNED8 = 0x05,
	MBX_T_UNSIGNED16 = 0x06,
	MBX_T_UNSIGNED32 = 0x07,
	MBX_T_REAL32 = 0x08,
	MBX_T_VISIBLE_STRING = 0x09,
	MBX_T_OCTET_STRING = 0x0A,
	MBX_T_UNICODE_STRING = 0x0B,
	MBX_T_TIME_OF_DAY = 0x0C,
	MBX_T_TIME_DIFFERENCE = 0x0D,
	MBX_T_DOMAIN = 0x0F,
	MBX_T_INTEGER24 = 0x10,
	MBX_T_REAL64 = 0x11,
	MBX_T_INTEGER40 = 0x12,
	MBX_T_INTEGER48 = 0x13,
	MBX_T_INTEGER56 = 0x14,
	MBX_T_INTEGER64 = 0x15,
	MBX_T_UNSIGNED24 = 0x16,
	MBX_T_UNSIGNED40 = 0x18,
	MBX_T_UNSIGNED48 = 0x19,
	MBX_T_UNSIGNED56 = 0x1A,
	MBX_T_UNSIGNED64 = 0x1B,
};

/* One of the basic types above. */
bool mbx_data_type_is_valid(unsigned type);

/* A device object: node of the line's bus, index:sub. `type` is the data
 * type (MBX_T_*) the client reads or writes it as; 0 = the one the line
 * knows (the node's DCF/EDS or "types"), else an unsigned integer of the
 * mapped size. */
typedef struct mbx_dev_obj_req {
	uint8_t node; /* 1..127 */
	uint8_t sub;
	uint16_t index;
	uint16_t type;
	uint16_t flags; /* MBX_DEV_* */
} mbx_dev_obj_req;

enum mbx_dev_flag {
	MBX_DEV_SDO_ONLY = 1u << 0, /* READ: never from the mirror; WRITE: never by PDO */
};

typedef struct mbx_dev_node_req {
	uint8_t node; /* 0 = every node the line knows */
	uint8_t pad[3];
} mbx_dev_node_req;

typedef struct mbx_dev_watch_req {
	mbx_dev_obj_req obj;
	uint32_t min_interval_ms; /* at most one event per interval (0 = every
	                           * value); the latest value is sent when it ends */
} mbx_dev_watch_req;

typedef struct mbx_dev_watch_resp {
	uint16_t type; /* MBX_T_* the values will carry */
	uint16_t pdo;  /* the device's TPDO that carries the object */
	uint32_t cob_id;
} mbx_dev_watch_resp;

typedef struct mbx_dev_read_req {
	mbx_dev_obj_req obj;
	uint32_t max_age_ms; /* a mirrored value at most this old is answered from the
	                      * mirror; 0 = the line's default, UINT32_MAX = any age */
} mbx_dev_read_req;

enum mbx_dev_via {
	MBX_DEV_VIA_PDO = 1, /* read: the mirror of a TPDO; write: an RPDO of the device */
	MBX_DEV_VIA_SDO = 2,
};

/* READ answer and MBX_EV_DEV_VALUE: fixed part, then `len` bytes of the
 * value in CiA 301 encoding (little-endian; strings as their bytes). */
typedef struct mbx_dev_value {
	uint8_t node;
	uint8_t sub;
	uint16_t index;
	uint16_t type;    /* MBX_T_* of the value */
	uint8_t via;      /* mbx_dev_via */
	uint8_t bits;     /* mapped length when via = PDO, else 0 */
	uint32_t seq;     /* event: per watch, +1 per event (a gap = events lost);
	                 * read: the mirror's count of values received */
	uint32_t age_ms;  /* read from the mirror: age of the value; else 0 */
	uint64_t time_us; /* CLOCK_MONOTONIC reception of the frame (PDO) or of
	                   * the SDO confirmation */
	uint32_t len;
	uint32_t pad;
} mbx_dev_value;

#define MBX_DEV_VALUE_EVENT_MAX 8u /* an event carries a PDO's value: <= 8 bytes */

/* DEV_LAYOUT answer: per node (the requested one, or every node the line
 * knows) one mbx_dev_layout_node, then its n_tpdo + n_rpdo PDO records
 * (the device's TPDOs first), each followed by its n entries. */
typedef struct mbx_dev_layout_node {
	uint8_t node;
	uint8_t source; /* 0 none, 1 file (DCF/EDS), 2 scan (SDO) */
	uint8_t valid;  /* 1: learnt and not invalidated since */
	uint8_t mirror; /* mbx_dev_mirror_status */
	uint8_t reason; /* mbx_dev_mirror_reason of the first PDO not mirrored */
	uint8_t pad;
	uint16_t missing;    /* valid PDOs not mirrored (with mirror on) */
	uint32_t generation; /* of the layout: +1 at every change */
	uint16_t n_tpdo;     /* records that follow */
	uint16_t n_rpdo;
	uint16_t dropped_tpdo; /* valid PDOs the table had no room for */
	uint16_t dropped_rpdo;
	uint64_t learned_us; /* CLOCK_MONOTONIC when learnt */
} mbx_dev_layout_node;

typedef struct mbx_dev_layout_pdo {
	uint16_t nr;  /* the device's PDO number, 1..512 */
	uint8_t dir;  /* 1 = a TPDO of the device, 0 = an RPDO */
	uint8_t n;    /* entries that follow */
	uint32_t cob; /* communication sub 1 */
	uint8_t tt;
	uint8_t sync_start;
	uint16_t inhibit; /* 100 us */
	uint16_t event_ms;
	uint8_t bytes;         /* frame length */
	uint8_t mirror_reason; /* mbx_dev_mirror_reason, 0 = mirrored or off */
	uint16_t mirror_pdo;   /* the daemon's PDO mirroring it (RPDO for a
	                        * TPDO of the device), 0 = none */
	uint16_t pad;
} mbx_dev_layout_pdo;

typedef struct mbx_dev_layout_entry {
	uint16_t index; /* 0001h..0007h: a dummy entry */
	uint8_t sub;
	uint8_t bits;
	uint8_t offset; /* first bit in the frame */
	uint8_t access; /* CO_ACC_* bits the file gives (1 read, 2 write,
	                 * 4 const, 8 RPDO, 16 TPDO), 0 = unknown */
	uint16_t type;  /* MBX_T_*, 0 = unknown */
} mbx_dev_layout_entry;

enum mbx_dev_mirror_status {
	MBX_DEV_MIRROR_OFF = 0,     /* pdo is not "auto" for the node */
	MBX_DEV_MIRROR_WAITING = 1, /* no valid layout */
	MBX_DEV_MIRROR_FULL = 2,    /* every valid PDO mirrored */
	MBX_DEV_MIRROR_PARTIAL = 3, /* some not (reason, missing) */
	MBX_DEV_MIRROR_NONE = 4,    /* none could be */
};

enum mbx_dev_mirror_reason {
	MBX_DEV_MR_NONE = 0,
	MBX_DEV_MR_NO_FREE_PDO = 1, /* the daemon has no free PDO record left */
	MBX_DEV_MR_COB_IN_USE = 2,  /* a PDO of the daemon already uses the COB-ID */
	MBX_DEV_MR_OD_REFUSED = 3,  /* the daemon's OD refused the re-mapping */
	MBX_DEV_MR_NOT_KEPT = 4,    /* beyond the layout table's room */
};

/* MBX_EV_DEV_MIRROR */
typedef struct mbx_ev_dev_mirror {
	uint8_t node;
	uint8_t status; /* mbx_dev_mirror_status */
	uint8_t reason; /* mbx_dev_mirror_reason */
	uint8_t pad;
	uint16_t mirrored; /* device PDOs mirrored */
	uint16_t missing;  /* not */
	uint32_t generation;
} mbx_ev_dev_mirror;

typedef struct mbx_dev_write_resp {
	uint8_t via;  /* mbx_dev_via */
	uint8_t held; /* PDO: not sent yet, another object of it has no value yet */
	uint16_t pdo; /* the device's RPDO (via PDO) */
	uint32_t cob_id;
} mbx_dev_write_resp;

/* DEV_FORWARDS: one per end of a forwarded device object on the line. */
typedef struct mbx_dev_forward {
	uint8_t source; /* 1: `from` end (a TPDO of node into the image), 0: `to` end */
	uint8_t node;
	uint8_t sub;
	uint8_t peer_line;
	uint16_t index;
	uint16_t image; /* the process image object B000h..BFFFh (sub 0) */
	uint8_t peer_node;
	uint8_t peer_sub;
	uint16_t peer_index;
	uint32_t values;     /* source: values put into the image; target: values
	                      * taken from it */
	uint32_t sent;       /* target: frames of the device's RPDO carrying one */
	uint32_t superseded; /* target: values replaced before a frame carried them */
	uint32_t refused;    /* values not forwarded: the device's PDO not mirrored, or
	                      * (target) a value its mapped bits cannot hold */
	uint32_t pad;
} mbx_dev_forward;

/* ---- functions ----------------------------------------------------------- */

/* Write the 48-byte header into buf (>= MBX_HDR_SIZE). */
void mbx_hdr_encode(const mbx_hdr *h, uint8_t *buf);
/*
 * Decode and check the envelope of a received message of n bytes:
 * size, magic, version, kind, len == n - header, flags, chunk/total
 * consistency, and the kind-specific rules (a command carries no status,
 * abort, dropped or OVERFLOW flag; a response/event carries no token).
 * Returns 0 or a negative mbx_status; *bad (optional) tells the reason.
 */
int mbx_hdr_decode(const uint8_t *buf, size_t n, mbx_hdr *h, mbx_bad *bad);

/*
 * Validate the payload of a command (its first message for a chunked one:
 * then only the fixed part is checked here; the data arrives in chunks).
 * Checks the size for the command and every field (node ids, NMT cs,
 * filters, queue names, pads zero). Returns 0 or a negative mbx_status,
 * *bad (optional) the reason.
 */
int mbx_cmd_validate(const mbx_hdr *h, const uint8_t *payload, mbx_bad *bad);

/* Check an event payload as a client receives it (sizes and counts). */
int mbx_event_validate(unsigned code, const uint8_t *payload, size_t len);

/* Readdress an encoded message (b: at least MBX_HDR_SIZE bytes) to
 * client: its id, and MBX_F_OVERFLOW with dropped when dropped != 0
 * (cleared otherwise). Lets one encoding serve every recipient of an event. */
void mbx_hdr_set_recipient(uint8_t *b, uint32_t client, uint32_t dropped);

/* Build a complete message: header (len set from payload_len) + payload.
 * Returns the message size, or -EMSGSIZE if it does not fit cap. */
int mbx_msg_build(uint8_t *buf, size_t cap, const mbx_hdr *h, const void *payload,
		  size_t payload_len);

/* A valid queue name: "/" + 1..62 chars of [A-Za-z0-9._-], NUL within the
 * field of MBX_QNAME_MAX bytes. */
bool mbx_queue_name_is_valid(const char *name, size_t field);
/* The queues of one client: "<stem>.resp" and "<stem>.evt", same stem of
 * at least "/" + one char (both names valid). */
bool mbx_client_queues_pair(const char *resp, const char *evt);
/* A valid instance name: 1..MBX_INSTANCE_MAX chars of [A-Za-z0-9_-]. */
bool mbx_instance_is_valid(const char *instance);
/* "/cogw.<instance>.line<N>.cmd". Returns 0, -EINVAL, -ENAMETOOLONG. */
int mbx_queue_name(char *buf, size_t cap, const char *instance, unsigned line);

/* An MBX_EV_APP_IND or MBX_EV_APP_WRITTEN payload (mailbox/proto_app.h):
 * its fixed part into *fixed (mbx_ev_app_ind / mbx_ev_app_written; NULL:
 * only check), *data (optional) at its inline_len bytes. 0 or
 * MBX_E_MALFORMED. */
int mbx_app_event_split(unsigned code, const void *p, size_t len, void *fixed,
			const uint8_t **data);

/* Does a raw frame match a filter? (see mbx_raw_filter) */
bool mbx_raw_filter_match(const mbx_raw_filter *f, const mbx_raw_frame *fr);

/*
 * Check the kernel limits for message queues of depth messages of msgsize
 * bytes: /proc/sys/fs/mqueue/msg_max, msgsize_max and RLIMIT_MSGQUEUE.
 * Returns 0, or -ERANGE with err naming the sysctl and the value needed
 * ("fs.mqueue.msg_max is 10, the mailbox needs 64: sysctl -w ..."), or
 * -errno if the limits cannot be read. The daemon calls it at start-up.
 */
int mbx_check_system_limits(unsigned depth, unsigned msgsize, char *err, size_t errlen);

#endif /* COGW_MAILBOX_PROTO_H */
