/* SPDX-License-Identifier: MIT */
/*
 * mailbox/proto_app.h - the wire format of objects a client owns on a
 * line's object dictionary (docs/application.md, docs/mailbox.md
 * "Application objects"). Included by proto.h; the codes are in its
 * tables (MBX_CMD_APP_*, MBX_EV_APP_*).
 *
 * A client with write access claims an object of the line's own node
 * (declared in the configuration for its user, or created at run time in
 * 2000h-5FFFh / 6000h-9FFFh) as
 *   held:   the daemon keeps the value (PDOs map it, SDO reads never wait);
 *           the owner writes it with OD_WRITE / PDO_WRITE and gets
 *           MBX_EV_APP_WRITTEN when someone else (SDO, another client, an
 *           RPDO) wrote it;
 *   served: every read and write (SDO from the bus, OD_READ/OD_WRITE and
 *           SDO_UPLOAD/DOWNLOAD to the own node from any client) reaches
 *           the owner as MBX_EV_APP_IND and is answered when the owner
 *           answers with APP_ANSWER (a write it refuses is not applied),
 *           or by the line itself with a documented abort code when the
 *           owner is late, gone or has too many indications open.
 */
#ifndef COGW_MAILBOX_PROTO_APP_H
#define COGW_MAILBOX_PROTO_APP_H

#include <stdint.h>

enum mbx_app_kind {
	MBX_APP_HELD = 1,
	MBX_APP_SERVED = 2,
};

/* mbx_app_claim_req.access (a CiA 301 access, as co_od_entry.access) */
enum mbx_app_access {
	MBX_APP_READ = 1u << 0,
	MBX_APP_WRITE = 1u << 1,
	MBX_APP_RPDO = 1u << 3, /* held only: may be mapped into an RPDO */
	MBX_APP_TPDO = 1u << 4, /* held only: may be mapped into a TPDO */
};
#define MBX_APP_ACCESS_MASK 0x1Bu

/* APP_CLAIM: claim (type 0: an object declared for the client's user, as
 * declared; kind must match) or create (type != 0: a new object of this
 * description; the same description again re-claims an object the client's
 * user created before). Trailing data: the default value (numerics: the
 * type's size; strings and DOMAIN: 0..max_size bytes). */
typedef struct mbx_app_claim_req {
	uint16_t index;
	uint8_t sub;
	uint8_t kind;   /* mbx_app_kind */
	uint16_t type;  /* CiA 301 data type (MBX_T_*), 0 = as declared */
	uint8_t access; /* mbx_app_access (creating), 0 = as declared */
	uint8_t pad;
	uint32_t max_size; /* strings and DOMAIN: capacity (1..MBX_APP_MAX_SIZE) */
	uint32_t pad2;
} mbx_app_claim_req;

#define MBX_APP_MAX_SIZE (1024u * 1024u) /* largest served/held string or DOMAIN */

/* APP_ANSWER: the owner's answer to an indication. abort 0 accepts a
 * write / answers a read with the trailing data (the value: numerics the
 * type's size, else 0..max_size bytes, chunked when large); an abort code
 * refuses (no data). */
typedef struct mbx_app_answer_req {
	uint32_t ind;   /* mbx_ev_app_ind.ind */
	uint32_t abort; /* 0 or the CiA 301 abort code of the refusal */
} mbx_app_answer_req;

/* APP_IND_DATA: the data of a write indication too large for its event
 * (mbx_ev_app_ind.inline_len < size); the answer streams all of it. */
typedef struct mbx_app_ind_req {
	uint32_t ind;
	uint32_t pad;
} mbx_app_ind_req;

enum mbx_app_op {
	MBX_APP_OP_READ = 1,
	MBX_APP_OP_WRITE = 2,
};

enum mbx_app_origin {
	MBX_APP_FROM_SDO = 1,     /* an SDO client on the bus */
	MBX_APP_FROM_MAILBOX = 2, /* a mailbox client (OD_*, SDO_* to the own node) */
	MBX_APP_FROM_RPDO = 3,    /* MBX_EV_APP_WRITTEN only */
};

/* MBX_EV_APP_IND (to the owner only, whatever its subscriptions):
 * answer it with APP_ANSWER before `deadline_ms` has passed. A write
 * carries the first inline_len bytes of its `size` bytes; the rest with
 * APP_IND_DATA. */
typedef struct mbx_ev_app_ind {
	uint32_t ind; /* the indication's id (answers name it) */
	uint16_t index;
	uint8_t sub;
	uint8_t op;      /* mbx_app_op */
	uint8_t origin;  /* mbx_app_origin */
	uint8_t channel; /* SDO: the server channel (0-based) */
	uint16_t inline_len;
	uint32_t size;        /* write: bytes of the new value */
	uint32_t deadline_ms; /* from now: the line answers by itself then */
	uint32_t client;      /* mailbox origin: the requester's client id */
	uint32_t pad;
} mbx_ev_app_ind;

/* MBX_EV_APP_WRITTEN (to the owner of a held object): someone else wrote
 * it; the first inline_len bytes of the new value follow (the rest:
 * OD_READ). */
typedef struct mbx_ev_app_written {
	uint16_t index;
	uint8_t sub;
	uint8_t origin; /* mbx_app_origin */
	uint16_t inline_len;
	uint16_t pdo; /* RPDO: its number (1..512), else 0 */
	uint32_t size;
	uint32_t client; /* mailbox origin: the writer's client id */
} mbx_ev_app_written;

/* MBX_EV_APP_CANCEL (to the owner): an indication ended without its
 * answer (the SDO client aborted, the deadline passed, ...); an answer
 * to it now is refused. */
typedef struct mbx_ev_app_cancel {
	uint32_t ind;
	uint32_t abort; /* what the requester got */
} mbx_ev_app_cancel;

/* APP_LIST answer: mbx_app_status, then n mbx_app_obj. */
typedef struct mbx_app_status {
	uint16_t n;           /* objects that follow */
	uint16_t max_objects; /* the line's bound (declared + created) */
	uint16_t max_per_client;
	uint16_t max_ind_per_client; /* open indications of one owner */
	uint32_t ind_sent;           /* indications handed to owners */
	uint32_t ind_answered;       /* answered in time */
	uint32_t ind_late;           /* answered by the line: deadline (08000020h) */
	uint32_t ind_no_owner;       /* answered by the line: no owner (08000021h) */
	uint32_t ind_refused_full;   /* answered by the line: too many open,
	                            * or the owner's event queue full (060A0023h) */
	uint32_t ind_cancelled;      /* the requester went first (abort, timeout) */
	uint32_t answers_refused;    /* answers to unknown / foreign / closed ones */
	uint32_t claims_refused;     /* APP_CLAIM refused (range, owner, bound) */
	uint32_t written_events;     /* MBX_EV_APP_WRITTEN sent */
	uint32_t pad;
} mbx_app_status;

typedef struct mbx_app_obj {
	uint16_t index;
	uint8_t sub;
	uint8_t kind;     /* mbx_app_kind */
	uint16_t type;    /* CiA 301 data type */
	uint8_t access;   /* mbx_app_access */
	uint8_t declared; /* 1: from the configuration, 0: created at run time */
	uint32_t owner;   /* client id, 0 = none */
	uint32_t uid;     /* the user who may claim it */
	uint32_t max_size;
	uint32_t open; /* indications open on it */
} mbx_app_obj;

#endif /* COGW_MAILBOX_PROTO_APP_H */
