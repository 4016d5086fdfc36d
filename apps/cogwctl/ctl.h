/* SPDX-License-Identifier: MIT */
/*
 * apps/cogwctl/ctl.h - what the files of cogwctl share: the invocation
 * context (global options, the libcogw handle), the exit codes, the option
 * parser, output helpers (human text or --json) and argument/value parsing.
 *
 * cogwctl is a client of the daemon like any other: it talks only through
 * libcogw (mailbox/cogw.h), never to CAN.
 */
#ifndef COGW_APPS_COGWCTL_CTL_H
#define COGW_APPS_COGWCTL_CTL_H

#include <cjson/cJSON.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "core/od.h"
#include "mailbox/cogw.h"

/* Exit codes (docs/cogwctl.md). */
enum ctl_exit {
	CTL_EXIT_OK = 0,
	CTL_EXIT_REFUSED = 1,   /* SDO abort, LSS error, the daemon refused */
	CTL_EXIT_USAGE = 2,     /* bad command line */
	CTL_EXIT_NO_DAEMON = 3, /* daemon (or that line) not reachable */
	CTL_EXIT_TIMEOUT = 4,   /* no answer in time (daemon or device) */
};

typedef struct ctl {
	const char *instance; /* --instance, $COGW_INSTANCE, "main" */
	unsigned timeout_ms;  /* --timeout: each exchange with the daemon */
	bool json;            /* --json: one JSON object per result/event */
	bool help;            /* --help seen after the subcommand */
	const char *what;     /* "sdo read", for messages */
	cogw *h;              /* opened on first use (ctl_handle) */
} ctl;

/* ---- options ----------------------------------------------------------- */

/* A subcommand option: "--name VALUE" / "--name=VALUE" (has_arg) or a
 * flag "--name". Global options (--json, --timeout, --instance, --help)
 * are accepted by every subcommand as well. */
typedef struct ctl_opt {
	const char *name;
	bool has_arg;
	const char **value; /* has_arg */
	bool *flag;         /* !has_arg */
} ctl_opt;

/* Split argv into options and positionals (at most max_pos). An argument
 * "-5" or "-0.5" is a positional (negative number), "--" ends options.
 * Returns 0 or CTL_EXIT_USAGE (message printed). */
int ctl_parse(ctl *c, int argc, char **argv, const ctl_opt *opts, const char **pos, int max_pos,
	      int *n_pos);
/* Parse one global option at argv[*i]; returns 1 if consumed, 0 if not a
 * global option, -1 on a usage error (message printed). */
int ctl_global_option(ctl *c, int argc, char **argv, int *i);

/* ---- output ------------------------------------------------------------ */

/* "cogwctl <what>: <message>" on stderr; returns CTL_EXIT_USAGE and
 * reminds of --help. */
int ctl_usage_error(ctl *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* Report a failed libcogw call (rc < 0, abort code for COGW_E_ABORT) and
 * return the matching exit code. Human: a line on stderr; --json: an
 * object {"ok":false,...} on stdout. context: "SDO upload 1018:01 node 1
 * on line 0". */
int ctl_fail(ctl *c, int rc, uint32_t abort, const char *context);
/* Exit code of a libcogw result. */
int ctl_exit_of(int rc, uint32_t abort);
/* Print a JSON object on one line and free it. */
void ctl_json_print(cJSON *o);
/* The libcogw handle, opened on first use. NULL: message printed, *exit
 * set. */
cogw *ctl_handle(ctl *c, int *exit_code);
/* "0x06020000 (object does not exist ...)" into buf. */
const char *ctl_abort_text(uint32_t abort, char *buf, size_t len);
/* A wall-clock timestamp "HH:MM:SS.mmm" of now. */
void ctl_timestamp(char *buf, size_t len, double *epoch_s);

/* ---- argument parsing: strict, 0 or -1 with *err set ------------------- */

int ctl_parse_u64(const char *s, uint64_t max, uint64_t *v, const char **err);
int ctl_parse_i64(const char *s, int64_t min, int64_t max, int64_t *v, const char **err);
/* LINE 0..63, NODE 1..127, INDEX hex (0x optional, "h" suffix allowed),
 * SUB 0..255 (decimal or 0x). */
int ctl_arg_line(ctl *c, const char *s, unsigned *line);
int ctl_arg_node(ctl *c, const char *s, uint8_t *node);
int ctl_arg_index(ctl *c, const char *s, uint16_t *index);
int ctl_arg_sub(ctl *c, const char *s, uint8_t *sub);
/* A number given as decimal or 0x hex within 0..max; name for messages. */
int ctl_arg_uint(ctl *c, const char *s, const char *name, uint64_t max, uint64_t *v);
/* A hex byte string "01 02 ff", "0102ff", "01:02:ff"; *n bytes into out
 * (cap). */
int ctl_parse_hex_bytes(const char *s, uint8_t *out, size_t cap, size_t *n, const char **err);
/* Read a whole file (for @file). Caller frees *data. */
int ctl_read_file(ctl *c, const char *path, uint8_t **data, size_t *len);

/* ---- values by type ------------------------------------------------------ */

/* The CiA 301 types values are given and shown as: libcogw's table
 * (mailbox/cogw.h cogw_type), shared with every client. */
typedef cogw_type ctl_type;

/* By short name or CiA name, case-insensitive; NULL if unknown. */
const ctl_type *ctl_type_find(const char *name);
/* "u8, u16, ..." for help and errors. */
const char *ctl_type_names(void);
/* Encode a VALUE (or @file for variable types) as the type's wire bytes.
 * *data is malloc'd. Returns 0 or an exit code (message printed). */
int ctl_value_encode(ctl *c, const ctl_type *t, const char *value, uint8_t **data, size_t *len);
/* Text of a value: "592", "-3", "12.5", "STI-SIM", "01 02 03". NULL type:
 * a guess (hex, plus the number if 1/2/4/8 bytes). Returns the text in a
 * malloc'd string. */
char *ctl_value_text(const ctl_type *t, const uint8_t *data, size_t len);
/* Add "value" (typed) and "hex" members for --json. */
void ctl_value_json(cJSON *o, const ctl_type *t, const uint8_t *data, size_t len);
/* Add member `name`: the REAL32/REAL64 (CO_T_*) of data's little-endian
 * bytes as a JSON number that reads back to the same bits (null for NaN
 * and infinities). */
void ctl_json_add_real(cJSON *o, const char *name, uint16_t type, const uint8_t *data);
/* "01 02 03" (no more than max bytes, then "..."); malloc'd. */
char *ctl_hex_text(const uint8_t *data, size_t len, size_t max);
/* The RPDO supervision faults in bits (MBX_RPDO_FAULT_*): "deadline missed",
 * "short", "long", joined by sep; with_emcy adds the EMCY code, e.g.
 * "short (8210h)". */
void ctl_rpdo_fault_text(uint8_t faults, const char *sep, bool with_emcy, char *buf, size_t len);

/* ---- subcommands ------------------------------------------------------- */

typedef struct ctl_cmd {
	const char *name;
	const char *synopsis;                      /* for the overview */
	const char *help;                          /* full --help text */
	int (*run)(ctl *c, int argc, char **argv); /* argv[0] = the name */
} ctl_cmd;

extern const ctl_cmd ctl_cmd_status, ctl_cmd_sdo, ctl_cmd_od, ctl_cmd_nmt, ctl_cmd_pdo,
	ctl_cmd_emcy, ctl_cmd_lss, ctl_cmd_monitor, ctl_cmd_raw, ctl_cmd_dcf, ctl_cmd_route,
	ctl_cmd_manager, ctl_cmd_boot, ctl_cmd_diag, ctl_cmd_program, ctl_cmd_configure,
	ctl_cmd_watch, ctl_cmd_dev, ctl_cmd_health, ctl_cmd_node, ctl_cmd_app, ctl_cmd_host,
	ctl_cmd_scan;

/* Run one(c, h, line, arr) for the lines given as
 * positionals (or every line of the daemon); with --json one object
 * {"ok":true,"instance":...,"lines":arr} of what each added to arr. */
int ctl_each_line(ctl *c, const char *const *pos, int n_pos,
		  int (*one)(ctl *c, cogw *h, unsigned line, cJSON *arr));
/* A whole command of the form `cogwctl CMD [LINE...]` (options, --help,
 * then ctl_each_line): its exit status. */
int ctl_run_lines(ctl *c, int argc, char **argv, const ctl_cmd *cmd,
		  int (*one)(ctl *c, cogw *h, unsigned line, cJSON *arr));

/* cmd_health.c: the health summary line of `status`, and its JSON. */
void ctl_health_summary_text(const mbx_line_health *hl);
void ctl_health_json(cJSON *o, const mbx_line_health *hl);

/* cmd_appwd.c: the application summary line of `status`, and its JSON
 * (wd: st->n entries). */
void ctl_appwd_summary_text(const mbx_appwd_status *st);
void ctl_appwd_json(cJSON *o, const mbx_appwd_status *st, const mbx_appwd_entry *wd);
/* cmd_appwd.c, for `app` (cmd_app.c): a line's watchdog, hold and host
 * ready, into o (--json) or printed; whether argv asks for essential or
 * hold, and running them (cmd: for --help). */
int ctl_appwd_show(ctl *c, cogw *h, unsigned line, cJSON *o);
bool ctl_appwd_wants(int argc, char **argv);
int ctl_appwd_run(ctl *c, int argc, char **argv, const ctl_cmd *cmd);

/* cmd_dev.c: "pdo map [LINE [NODE]]" (pos[0] = "map"). */
int ctl_pdo_map(ctl *c, int n_pos, const char **pos);

/* Print a subcommand's help (stdout) and return 0. */
int ctl_print_help(const ctl_cmd *cmd);

/* monitor.c: the event loop shared by "monitor" and "raw dump". */
typedef struct ctl_monitor_spec {
	uint64_t lines;   /* bit per line; 0 = every line of the daemon */
	uint32_t classes; /* MBX_EVC_* */
	mbx_raw_filter filters[MBX_RAW_FILTERS_MAX];
	size_t n_filters;
	uint64_t count;    /* stop after this many events, 0 = no limit */
	double duration_s; /* stop after this long, 0 = no limit */
	bool as_float;     /* PDO values of 4 bytes as REAL32 */
} ctl_monitor_spec;
int ctl_monitor_run(ctl *c, const ctl_monitor_spec *spec);
/* One event as monitor prints it (text line or --json object). */
void ctl_monitor_print(ctl *c, const cogw_msg *m, const ctl_monitor_spec *spec);
/* "ID[/MASK]" (3 hex digits or fewer = 11-bit, 8 = 29-bit). */
int ctl_parse_raw_filter(ctl *c, const char *s, mbx_raw_filter *f);
/* Number of lines of the daemon (probes line queues 0, 1, ...). Returns
 * >= 1 or an exit code as a negative number. */
int ctl_count_lines(ctl *c);
/* The gateway counters of one line (cmd_route.c; also cogwctl status):
 * as members of o, and as three text lines after indent. */
void ctl_gw_counters_json(cJSON *o, const mbx_gw_status *st);
void ctl_gw_counters_text(const mbx_gw_status *st, const char *indent);

#endif /* COGW_APPS_COGWCTL_CTL_H */
