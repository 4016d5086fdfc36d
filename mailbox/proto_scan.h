/* SPDX-License-Identifier: MIT */
/*
 * mailbox/proto_scan.h - the wire format of the node scan and of unknown
 * nodes (docs/mailbox.md "Node scan and unknown nodes"): NODE_SCAN's
 * request and answer, NODE_SCAN_CACHE's answer and the UNKNOWN_NODE
 * event. Included by mailbox/proto.h, whose enums hold the codes;
 * little-endian, fixed sizes like every mailbox payload.
 */
#ifndef COGW_MAILBOX_PROTO_SCAN_H
#define COGW_MAILBOX_PROTO_SCAN_H

#include <stdint.h>

#define MBX_SCAN_TIMEOUT_MAX_MS 5000u /* per SDO frame of a scan */

/* NODE_SCAN: read 1000h and 1018h:1..4 of node-IDs first..last. */
typedef struct mbx_scan_req {
	uint8_t first, last; /* 1 <= first <= last <= 127 */
	uint16_t timeout_ms; /* per SDO frame, 1..MBX_SCAN_TIMEOUT_MAX_MS;
	                       * 0 = the line's unknown_nodes.sdo_timeout_ms */
	uint8_t parallel;    /* nodes asked at once; 0 = the line's SDO
	                       * client channels (more are not used) */
	uint8_t pad[3];
} mbx_scan_req;

/* How a node came into the line's cache. */
enum mbx_ident_source {
	MBX_IDENT_SCAN = 0,      /* NODE_SCAN */
	MBX_IDENT_BOOTUP = 1,    /* an unknown node's boot-up */
	MBX_IDENT_HEARTBEAT = 2, /* an unknown node's heartbeat */
	MBX_IDENT_EMCY = 3,      /* an unknown node's EMCY */
};

/* "scan", "boot-up", "heartbeat", "emcy"; "?" otherwise. */
static inline const char *mbx_ident_source_to_string(unsigned s)
{
	static const char *const names[] = { "scan", "boot-up", "heartbeat", "emcy" };
	return s < sizeof names / sizeof names[0] ? names[s] : "?";
}

enum mbx_ident_flag {
	MBX_IDENT_PRESENT = 1u << 0,  /* 1000h answered (or an abort came back) */
	MBX_IDENT_IDENTITY = 1u << 1, /* 1018h:1..3 read */
	MBX_IDENT_SERIAL = 1u << 2,   /* 1018h:4 read */
	MBX_IDENT_NOT_ASKED = 1u << 3 /* not read: the node was STOPPED (no SDO,
	                               * CiA 301 §7.3.2.2), or the line reads no
	                               * identities (unknown_nodes.identify) */
};

/* One node as read. */
typedef struct mbx_node_ident {
	uint8_t node;
	uint8_t flags;     /* enum mbx_ident_flag */
	uint8_t source;    /* enum mbx_ident_source */
	uint8_t nmt_state; /* last heard (mbx_node_entry's), 0xFF unknown */
	uint32_t device_type;
	uint32_t vendor_id, product_code, revision, serial;
	uint32_t abort;  /* of the first read that failed (0 = none) */
	uint32_t age_ms; /* since it was read (saturates) */
} mbx_node_ident;

/* NODE_SCAN answer (when the scan ended) and NODE_SCAN_CACHE answer (the
 * last scan's figures, every node the line knows of): this, then found
 * mbx_node_ident entries, by node-ID. */
typedef struct mbx_scan_resp {
	uint8_t first, last; /* the scan's range (0, 0: no scan ran yet) */
	uint8_t found;       /* entries that follow */
	uint8_t parallel;    /* nodes asked at once */
	uint16_t timeout_ms; /* per SDO frame */
	uint16_t pad;
	uint32_t duration_ms; /* from the request to the answer */
	uint32_t requests;    /* SDO requests the scan made */
	uint32_t bound_ms;    /* the documented bound for this scan */
	uint32_t age_ms;      /* CACHE: since the last scan ended, saturates;
	                       * 0xFFFFFFFF = none yet */
} mbx_scan_resp;

/* What a line does with a node it was not configured for
 * (docs/config.md "unknown_nodes"). */
enum mbx_unknown_policy {
	MBX_UNKNOWN_IGNORE = 0,    /* report it, nothing else */
	MBX_UNKNOWN_SUPERVISE = 1, /* report it, consume its heartbeat */
	MBX_UNKNOWN_BOOT = 2,      /* report it, boot it as an optional slave
	                            * with the device file its identity matches */
};

/* "ignore", "supervise", "boot"; "?" otherwise. */
static inline const char *mbx_unknown_policy_to_string(unsigned p)
{
	static const char *const names[] = { "ignore", "supervise", "boot" };
	return p < sizeof names / sizeof names[0] ? names[p] : "?";
}

/* What came of the policy. */
enum mbx_unknown_action {
	MBX_UNKNOWN_NONE = 0,        /* ignore: nothing done */
	MBX_UNKNOWN_SUPERVISED = 1,  /* a heartbeat consumer (1016h) watches it */
	MBX_UNKNOWN_BOOTING = 2,     /* the manager boots it (MANAGER events follow) */
	MBX_UNKNOWN_NO_MATCH = 3,    /* boot: no device file has its identity */
	MBX_UNKNOWN_NO_IDENTITY = 4, /* boot: its identity could not be read */
	MBX_UNKNOWN_REFUSED = 5,     /* not possible: 1016h full, no manager, ... */
};

/* "none", "supervised", "booting", "no-match", "no-identity", "refused". */
static inline const char *mbx_unknown_action_to_string(unsigned a)
{
	static const char *const names[] = { "none",     "supervised",  "booting",
					     "no-match", "no-identity", "refused" };
	return a < sizeof names / sizeof names[0] ? names[a] : "?";
}

/* MBX_EV_UNKNOWN_NODE: a node outside the configuration was heard, once
 * per node-ID and daemon run, after its identity was read. */
typedef struct mbx_ev_unknown_node {
	mbx_node_ident ident;
	uint8_t policy; /* enum mbx_unknown_policy */
	uint8_t action; /* enum mbx_unknown_action */
	uint16_t heartbeat_ms;
	uint32_t reported; /* unknown nodes this line reported so far */
} mbx_ev_unknown_node;

#endif /* COGW_MAILBOX_PROTO_SCAN_H */
