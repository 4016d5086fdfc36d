/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-ascii/ascii_parse.h - one CiA 309-3 command line into a
 * command (docs/ascii.md "Commands"). No I/O, no allocation, no global
 * state: the same code runs in the gateway, the unit tests and the fuzz
 * target (tests/fuzz/fuzz_ascii.c).
 *
 *     [<seq>] [[<net>] <node>] r[ead]  <index> <sub> [<type>]
 *     [<seq>] [[<net>] <node>] w[rite] <index> <sub> <type> <value>
 *     [<seq>] [[<net>] <node|all>] start | stop | preop[erational]
 *                                | reset node | reset comm[unication]
 *     [<seq>] [<net>] set network|node|sdo_timeout|sdo_block <value>
 *     [<seq>] [<net>] lss_* ...
 *     [<seq>] info version | help [datatype|lss] | events ...
 *
 * The line comes without its line end ("\n" or "\r\n": the caller strips
 * both). '#' outside a quoted string starts a comment.
 */
#ifndef COGW_ASCII_PARSE_H
#define COGW_ASCII_PARSE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "apps/cogw-ascii/ascii_value.h"

/* CiA 309-3 error numbers ("[seq] ERROR: <n>"); SDO aborts are printed as
 * their abort code instead (0x06020000). */
enum ascii_err {
	ASCII_OK = 0,
	ASCII_E_UNSUPPORTED = 100, /* request not supported */
	ASCII_E_SYNTAX = 101,      /* syntax error */
	ASCII_E_STATE = 102,       /* not processed due to internal state */
	ASCII_E_TIMEOUT = 103,     /* time-out */
	ASCII_E_NO_NET = 104,      /* no default net set */
	ASCII_E_NO_NODE = 105,     /* no default node set */
	ASCII_E_NET = 106,         /* unsupported net */
	ASCII_E_NODE = 107,        /* unsupported node */
	ASCII_E_HB_STARTED = 202,  /* unsolicited: heartbeat started */
	ASCII_E_HB_LOST = 203,     /* unsolicited: heartbeat lost */
	ASCII_E_BOOT_UP = 205,     /* unsolicited: boot-up */
	ASCII_E_LSS_VENDOR = 501,  /* LSS implementation-specific error */
	ASCII_E_LSS_NODE = 502,    /* LSS node-ID not supported */
	ASCII_E_LSS_BITRATE = 503, /* LSS bit rate not supported */
	ASCII_E_LSS_STORE = 504,   /* LSS parameter storing failed */
	ASCII_E_LSS_MEDIA = 505,   /* LSS failed because of a media error */
	ASCII_E_MEMORY = 600,      /* running out of memory */
};

typedef enum ascii_verb {
	ASCII_V_NONE, /* empty or comment only: nothing is answered */
	ASCII_V_READ,
	ASCII_V_WRITE,
	ASCII_V_NMT_START,
	ASCII_V_NMT_STOP,
	ASCII_V_NMT_PREOP,
	ASCII_V_NMT_RESET_NODE,
	ASCII_V_NMT_RESET_COMM,
	ASCII_V_SET_NETWORK,
	ASCII_V_SET_NODE,
	ASCII_V_SET_SDO_TIMEOUT,
	ASCII_V_SET_SDO_BLOCK,
	ASCII_V_LSS_SWITCH_GLOB,
	ASCII_V_LSS_SWITCH_SEL,
	ASCII_V_LSS_SET_NODE,
	ASCII_V_LSS_CONF_BITRATE,
	ASCII_V_LSS_ACTIVATE_BITRATE,
	ASCII_V_LSS_STORE,
	ASCII_V_LSS_INQUIRE_ADDR,
	ASCII_V_LSS_GET_NODE,
	ASCII_V_LSS_FASTSCAN,
	ASCII_V_LSS_IDENT_NONCONF,
	ASCII_V_INFO_VERSION,
	ASCII_V_HELP,
	ASCII_V_EVENTS, /* non-standard: events on|off [class ...] */
} ascii_verb;

/* Event classes a connection may ask for (events on <class>...). */
enum ascii_event_class {
	ASCII_EV_EMCY = 1u << 0,
	ASCII_EV_BOOT = 1u << 1,    /* boot-up messages */
	ASCII_EV_HB = 1u << 2,      /* heartbeat started / lost */
	ASCII_EV_NMT = 1u << 3,     /* NMT state changes */
	ASCII_EV_MANAGER = 1u << 4, /* the manager's boot steps */
	ASCII_EV_ALL = 0x1Fu,
};

typedef struct ascii_cmd {
	bool has_seq;
	uint32_t seq;
	int net;  /* 1..127; -1 = not given (the connection's default) */
	int node; /* 0..127 (0 = all nodes, NMT only); -1 = not given */
	ascii_verb verb;
	uint16_t index;
	uint8_t sub;
	const ascii_type *type; /* read: NULL = none given (printed as hex) */
	size_t data_len;        /* write: encoded value bytes in the caller's buffer */
	uint32_t args[4];       /* set value; LSS arguments */
	unsigned n_args;
	uint32_t events; /* ASCII_EV_* */
	bool events_on;
	uint8_t help_topic; /* 0 general, 1 datatype, 2 lss */
} ascii_cmd;

/*
 * Parse line[0..len) into *cmd; a write's value is encoded into
 * data[0..cap). Returns ASCII_OK or an ascii_err number. The sequence
 * number is taken first, so cmd->has_seq/seq are valid on an error too
 * (the error line carries it).
 */
int ascii_parse(const char *line, size_t len, ascii_cmd *cmd, uint8_t *data, size_t cap);

/* "read", "nmt start", ... (logs, the conformance table). */
const char *ascii_verb_to_string(ascii_verb v);

/* Whether a verb changes something on the bus (refused to read-only
 * connections, docs/ascii.md "Security model"). */
bool ascii_verb_writes(ascii_verb v);

#endif /* COGW_ASCII_PARSE_H */
