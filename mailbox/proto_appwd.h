/* SPDX-License-Identifier: MIT */
/*
 * mailbox/proto_appwd.h - the wire format of the application watchdog, the
 * hold on the daemon's own OPERATIONAL and host ready / not ready
 * (docs/mailbox.md "The application watchdog and host ready",
 * docs/application.md). Included by mailbox/proto.h, whose enums hold the
 * command and event codes; little-endian, fixed sizes like every mailbox
 * payload, pad fields zero.
 */
#ifndef COGW_MAILBOX_PROTO_APPWD_H
#define COGW_MAILBOX_PROTO_APPWD_H

#include <stddef.h>
#include <stdint.h>

/* Reactions of the application watchdog (bits). At most one NMT reaction. */
enum mbx_appwd_reaction {
	MBX_APPWD_R_EMCY = 1u << 0,           /* own EMCY 6200h: [00 62 81 00 00 00 00 00] */
	MBX_APPWD_R_NMT_PREOP = 1u << 1,      /* NMT enter pre-operational, all nodes */
	MBX_APPWD_R_NMT_STOP = 1u << 2,       /* NMT stop, all nodes */
	MBX_APPWD_R_NMT_RESET_COMM = 1u << 3, /* NMT reset communication, all nodes */
	MBX_APPWD_R_NMT_RESET_NODE = 1u << 4, /* NMT reset node, all nodes */
	MBX_APPWD_R_HB_STOP = 1u << 5,        /* own heartbeat producer stops */
	MBX_APPWD_R_SAFE_OUTPUTS = 1u << 6,   /* the line's safe outputs */
	MBX_APPWD_R_CONFIGURED = 1u << 31,    /* request only: the line's configured set */
};
#define MBX_APPWD_R_ALL 0x7Fu
#define MBX_APPWD_R_NMT                                                              \
	(MBX_APPWD_R_NMT_PREOP | MBX_APPWD_R_NMT_STOP | MBX_APPWD_R_NMT_RESET_COMM | \
	 MBX_APPWD_R_NMT_RESET_NODE)
#define MBX_APPWD_INTERVAL_MIN_MS 10u
#define MBX_APPWD_INTERVAL_MAX_MS 60000u
#define MBX_APPWD_MAX 4u /* essential clients per line */

/* "emcy", "nmt-preop", "nmt-stop", "nmt-reset-comm", "nmt-reset-node",
 * "hb-stop", "safe-outputs"; "?" for anything but one known bit. */
const char *mbx_appwd_reaction_to_string(uint32_t bit);
/* "emcy,nmt-stop" ("none" for 0). Returns the length snprintf would. */
int mbx_appwd_reactions_format(uint32_t set, char *buf, size_t cap);
/* A comma-separated list of those names. 0, or -1 (an unknown name, an
 * empty list). */
int mbx_appwd_reactions_parse(const char *text, uint32_t *set);

/* APP_WATCHDOG: declare the client essential for the line (interval_ms
 * MBX_APPWD_INTERVAL_MIN_MS..MAX), or withdraw (interval_ms 0, reactions 0). */
typedef struct mbx_appwd_req {
	uint32_t interval_ms;
	uint32_t reactions; /* enum mbx_appwd_reaction, or MBX_APPWD_R_CONFIGURED */
} mbx_appwd_req;

typedef struct mbx_appwd_resp {
	uint32_t reactions;   /* the set in force */
	uint32_t unavailable; /* of those, what the line cannot do now (no NMT
	                       * master, no safe outputs configured): skipped
	                       * at a trip */
} mbx_appwd_resp;

/* APP_HOLD: 1 = hold the daemon's own node out of OPERATIONAL, 0 = ready. */
typedef struct mbx_appwd_hold_req {
	uint8_t hold;
	uint8_t pad[3];
} mbx_appwd_hold_req;

/* The APP_HOLD answer and the APP_NMT event. */
enum mbx_appwd_nmt_flag {
	MBX_APPWD_NMT_REFUSED = 1u << 0,  /* event: a start was refused (held) */
	MBX_APPWD_NMT_DEFERRED = 1u << 1, /* a refused start waits for the release */
	MBX_APPWD_NMT_HOST_NOT_READY = 1u << 2,
};

typedef struct mbx_appwd_nmt {
	uint8_t state;   /* the own node's NMT state (heartbeat byte values) */
	uint8_t prev;    /* event: the state before (= state when refused) */
	uint8_t cs;      /* event: the command that caused it, 0 = none */
	uint8_t flags;   /* enum mbx_appwd_nmt_flag */
	uint8_t holders; /* clients holding the node out of OPERATIONAL */
	uint8_t node;    /* the own node-ID */
	uint8_t pad[2];
} mbx_appwd_nmt;

/* HOST_READY: 1 = ready, 0 = not ready. */
typedef struct mbx_host_ready_req {
	uint8_t ready;
	uint8_t pad[3];
} mbx_host_ready_req;

/* APP_STATUS answer: mbx_appwd_status + n × mbx_appwd_entry. */
typedef struct mbx_appwd_status {
	uint8_t host_ready;
	uint8_t own_state; /* own NMT state */
	uint8_t holders;
	uint8_t flags;             /* enum mbx_appwd_nmt_flag (DEFERRED, HOST_NOT_READY) */
	uint32_t configured;       /* the line's configured reaction set */
	uint16_t safe_outputs;     /* safe outputs configured */
	uint8_t nmt_master;        /* the line can carry out NMT reactions */
	uint8_t n;                 /* entries that follow */
	uint32_t not_ready_action; /* the NMT command (cs) host not ready sends */
	uint64_t declared, keepalives, refused, trips, late_keepalives;
	uint64_t not_ready_episodes;
	uint64_t starts_refused; /* starts of the own node refused while held */
	/* the last trip: 0 when none */
	uint32_t last_client, last_pid;
	uint32_t last_done;    /* reactions carried out */
	uint32_t last_late_us; /* after the deadline */
	uint64_t last_age_ms;
} mbx_appwd_status;

typedef struct mbx_appwd_entry {
	uint32_t client;
	uint32_t pid;
	uint32_t interval_ms;
	uint32_t reactions;
	uint8_t state; /* 1 declared, 2 armed, 3 tripped */
	uint8_t gone;  /* its client left; it still trips at its deadline */
	uint8_t pad[2];
	uint32_t left_ms; /* armed: until the deadline */
	uint64_t keepalives;
} mbx_appwd_entry;

/* APP_WD_TIMEOUT event: an essential client missed its deadline. */
typedef struct mbx_ev_appwd {
	uint32_t client;
	uint32_t pid;
	uint32_t interval_ms;
	uint32_t reactions;   /* declared */
	uint32_t done;        /* carried out */
	uint32_t late_us;     /* the reactions ran this long after the deadline */
	uint64_t deadline_us; /* CLOCK_MONOTONIC */
	uint32_t trips;       /* of the line, this one included */
	uint8_t gone;         /* the client had left the mailbox (died, lease) */
	uint8_t pad[3];
} mbx_ev_appwd;

/* HOST_STATE event: host ready / not ready changed. */
typedef struct mbx_ev_host {
	uint8_t ready;
	uint8_t pad[3];
	uint32_t client; /* who said it */
	uint32_t done;   /* not ready: MBX_APPWD_R_SAFE_OUTPUTS and the NMT reaction
	                  * carried out (enum mbx_appwd_reaction bits) */
	uint32_t pad2;
} mbx_ev_host;

#endif /* COGW_MAILBOX_PROTO_APPWD_H */
