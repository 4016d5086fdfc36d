/* SPDX-License-Identifier: MIT */
/*
 * apps/common/config.h - cogwd's configuration (etc/cogw.json), parsed and
 * validated with cJSON. Every error names the file, the JSON path and the
 * reason, e.g.
 *   etc/cogw.json: lines[1].node_id: 200 is out of range 1..127
 * and the daemon refuses to start on any error. Reference: docs/config.md.
 *
 * Called by the main thread only, at start-up and on SIGHUP (reload).
 */
#ifndef COGW_APPS_CONFIG_H
#define COGW_APPS_CONFIG_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "apps/common/eds_pdo.h"
#include "apps/common/node_config.h"
#include "core/appwd.h"
#include "core/od.h"

#define COGW_LINES_MAX 16
#define COGW_ACCESS_RULES_MAX 64
#define COGW_HB_CONSUMERS_MAX 127
#define COGW_NAME_MAX 32

/* Mailbox access levels (mirror mailbox/proto.h enum mbx_access). */
typedef enum cogw_access_level {
	COGW_ACCESS_NONE = 0,
	COGW_ACCESS_READ = 1,
	COGW_ACCESS_WRITE = 2,
} cogw_access_level;

typedef struct cogw_access_rule {
	uid_t uid;      /* from "uid", or "user" resolved with getpwnam */
	uint8_t access; /* cogw_access_level */
} cogw_access_rule;

typedef struct cogw_rt_config {
	int priority; /* SCHED_FIFO 1..99, 0 = normal scheduling */
	int cpu;      /* pin to this CPU, -1 = no affinity */
} cogw_rt_config;

typedef struct cogw_hb_consumer {
	uint8_t node_id;
	uint16_t time_ms;
} cogw_hb_consumer;

/* What the line learns of its slaves' PDOs ("pdo"; docs/config.md "PDO
 * layouts"). */
typedef enum cogw_pdo_mode {
	COGW_PDO_OFF = 0, /* nothing learnt by SDO (a file's layout is still kept) */
	COGW_PDO_LEARN,   /* learn the layout: from the file, else by SDO scan */
	COGW_PDO_AUTO,    /* learn it and mirror the PDOs (the device object layer) */
} cogw_pdo_mode;

/* "off", "learn", "auto". */
const char *cogw_pdo_mode_to_string(uint8_t mode);

#define COGW_PDO_SCAN_MAX_DEFAULT 8u

/* A slave node on a line ("nodes"): its id, where its configuration
 * comes from (apps/common/node_config.h) and, for the line's CiA 302-2
 * manager, its assignment and expected identity. */
typedef struct cogw_node {
	uint8_t id;              /* 1..127, not the line's own node_id */
	cogw_node_config config; /* source NONE: nothing to download */
	uint32_t assignment;     /* 1F81h:n built from the names */
	uint32_t identity[5];    /* 1F84h..1F88h:n (0 = do not check) */
	uint16_t heartbeat_ms;   /* 1016h consumer time, 0 = none */
	bool keep_op;            /* restart it when it leaves OPERATIONAL */
	uint8_t target_state;    /* "state": NMT state after its boot
	                             * (CO_NMT_OPERATIONAL, PRE_OPERATIONAL or
	                             * STOPPED, core/nmt.h) */
	uint32_t software_id;    /* 1F55h:n expected software (0 = none);
	                             * non-zero sets 1F81h:n bit 5 */
	char program_file[256];  /* "program": the image file (resolved) */
	const uint8_t *program;  /* its bytes (read at load time, held by
	                             * cogw_config.files, shared by the nodes
	                             * naming the same file):
	                             * the 1F58h:n image; "software_update"
	                             * sets 1F81h:n bit 6 */
	size_t program_len;
	/* PDO layout (docs/config.md "PDO layouts") */
	uint8_t pdo;                  /* cogw_pdo_mode: "pdo", else the line's */
	char eds[COGW_FILE_NAME_MAX]; /* "eds": the device's file (resolved), "" = none */
	bool pdo_from_file;           /* the layout is pdo_file (config.dcf without
	                                   * "eds", or "eds" without "config") */
	eds_pdo_file pdo_file;        /* the valid PDOs the file gives (owned) */
	co_pdo_layout_type *types;    /* sorted: the file's objects with "types" over
	                                   * them (owned) */
	size_t n_types;
} cogw_node;

#define COGW_PROGRAM_MAX (16u * 1024u * 1024u)

/* The CiA 302-2 manager of a line ("manager"; docs/config.md). */
typedef struct cogw_manager_config {
	bool enabled;            /* the section is present */
	uint32_t nmt_startup;    /* 1F80h built from the names */
	uint32_t boot_time_ms;   /* 1F89h (0 = wait for ever) */
	uint32_t retry_ms;       /* retry interval of missing nodes */
	uint32_t scan_ms;        /* scan for missing nodes, 0 = off */
	uint32_t reset_wait_ms;  /* longest wait for a boot-up */
	uint32_t sdo_timeout_ms; /* per SDO frame during the boot */
	uint8_t max_parallel;    /* nodes booting at once, 0 = channels */
	bool accept_remote_nmt;  /* NMT to our node from the bus applies */
} cogw_manager_config;

/* "device_objects" of a line (docs/config.md, docs/devices.md). */
typedef struct cogw_devobj_config {
	uint32_t read_max_age_ms; /* DEV_READ answered from the mirror up to this age */
	uint32_t write_update_ms; /* writes to one device RPDO coalesced over this */
	uint16_t watches;         /* watch table of the line */
} cogw_devobj_config;

/* The application watchdog's keys of a line's "app": its configured
 * reactions, host not ready's NMT action, the safe outputs (docs/config.md,
 * docs/application.md). */
#define COGW_SAFE_OUTPUTS_MAX 32u
typedef struct cogw_appwd_config {
	uint32_t reactions;   /* "watchdog_reactions" (core/appwd.h bits), 0 = none */
	uint8_t not_ready_cs; /* "not_ready_nmt": CO_NMT_CS_STOP / _ENTER_PREOP */
	uint8_t n_safe_outputs;
	co_safe_output safe_outputs[COGW_SAFE_OUTPUTS_MAX];
} cogw_appwd_config;

/* A device file of "unknown_nodes.devices_dir" (docs/config.md
 * "unknown_nodes"): the identity it describes and the concise DCF a node
 * of that identity gets, for every node-ID ($NODEID resolved). */
typedef struct cogw_unknown_device {
	char file[COGW_FILE_NAME_MAX];
	uint32_t ident[4];  /* 1000h, 1018h:1..3 of the file (0 = any) */
	uint8_t *cdcf[128]; /* by node-ID; entries may share one buffer
	                      * (shared set: the file has no $NODEID) */
	size_t cdcf_len[128];
	bool shared;
} cogw_unknown_device;

#define COGW_UNKNOWN_DEVICES_MAX 64u

/* A line's "unknown_nodes". */
typedef struct cogw_unknown_config {
	uint8_t policy;                       /* enum mbx_unknown_policy */
	uint16_t heartbeat_ms;                /* supervise, boot: 1016h consumer time */
	uint16_t sdo_timeout_ms;              /* identity reads and scans, per frame */
	bool identify;                        /* read an unknown node's identity (SDO) */
	char devices_dir[COGW_FILE_NAME_MAX]; /* boot: resolved, "" = none */
	cogw_unknown_device *devices;         /* owned, n_devices */
	size_t n_devices;
} cogw_unknown_config;

void cogw_unknown_config_free(cogw_unknown_config *u); /* accepts zeroed */
/* "app" of a line: objects clients own (docs/application.md). */
#define COGW_APP_DECL_MAX 256
typedef struct cogw_app_decl {
	uint16_t index;
	uint8_t sub;
	uint8_t kind; /* mbx_app_kind */
	uint32_t uid;
} cogw_app_decl;

typedef struct cogw_app_config {
	uint16_t max_created;    /* run-time objects of the line (100) */
	uint16_t max_per_client; /* (64) */
	uint16_t indications;    /* open to one owner (8) */
	cogw_app_decl decl[COGW_APP_DECL_MAX];
	uint16_t n_decl;
} cogw_app_config;

typedef struct cogw_line_config {
	char name[COGW_NAME_MAX];      /* "line0" (default "line<N>") */
	char interface[COGW_NAME_MAX]; /* "vcan0" (IFNAMSIZ-1 chars max) */
	uint32_t bitrate;              /* 10k..1M, a CiA 301 bit rate */
	uint8_t node_id;               /* our own node id, 1..127 */
	uint16_t network_id;           /* CiA 302-7 network id, 1..127, unique */
	cogw_rt_config rt;
	/* SDO channels of our own node */
	uint8_t sdo_servers;                                  /* 1..128 (default 1) */
	uint8_t sdo_clients;                                  /* 0..128 (default 4) */
	uint32_t sdo_timeout_ms;                              /* per frame (default 1000) */
	uint32_t sdo_block_threshold;                         /* bytes (default 128) */
	uint16_t heartbeat_ms;                                /* 1017h (default 1000, 0 = off) */
	uint32_t sync_period_us;                              /* 1006h, 0 = no SYNC producer */
	uint32_t time_period_ms;                              /* TIME producer period, 0 = none */
	cogw_hb_consumer hb_consumers[COGW_HB_CONSUMERS_MAX]; /* 1016h */
	size_t n_hb_consumers;
	/* bus health (docs/troubleshooting.md): an episode is over after this
	 * silence, a node-ID conflict / lost frames */
	uint32_t id_conflict_quiet_ms;
	uint32_t fault_quiet_ms;
	/* The line's object dictionary: the standard communication objects
	 * for node_id, then "objects" (manufacturer/profile additions), then
	 * "values" (initial values of any object). Owned by the config. */
	co_od *od;
	cogw_node *nodes; /* "nodes" (owned, n_nodes entries) */
	size_t n_nodes;
	cogw_manager_config manager;       /* "manager" */
	uint8_t pdo;                       /* cogw_pdo_mode, the nodes' default */
	uint16_t pdo_scan_max;             /* PDOs per direction scanned and kept, 1..512 */
	cogw_devobj_config device_objects; /* "device_objects" */
	cogw_unknown_config unknown;       /* "unknown_nodes" */
	cogw_app_config app;               /* "app": objects clients own */
	cogw_appwd_config appwd;           /* "app": the watchdog, host not ready */
} cogw_line_config;

typedef struct cogw_mailbox_config {
	char instance[COGW_NAME_MAX]; /* queue names /<instance>.line<N>.cmd */
	unsigned depth;               /* mq_maxmsg of the command queues (64) */
	unsigned msg_size;            /* mq_msgsize (1024) */
	unsigned queue_mode;          /* command queue mode (0620) */
	unsigned max_clients;         /* per line (16) */
	unsigned lease_ms;            /* 0 = no lease */
	unsigned max_transfer;        /* bytes of one chunked transfer (1 MiB) */
	/* per-user / per-client limits (docs/mailbox.md "Security model";
	 * 0 = mbx_server's default, which depends on max_clients or
	 * transfer_slots) */
	unsigned max_clients_per_uid;
	unsigned max_outstanding;        /* requests of one client (16) */
	unsigned max_read_outstanding;   /* of all read-only clients (32) */
	unsigned write_reserve;          /* client slots for writers only */
	unsigned max_request_timeout_ms; /* ceiling of a request's timeout */
	unsigned transfer_slots;         /* chunked transfers at once (2) */
	unsigned max_transfers_per_client;
	unsigned transfer_stall_ms;    /* no progress: slot freed (5000) */
	unsigned transfer_lifetime_ms; /* in all: slot freed (60000) */
	/* Bytes all lines' transfers may use at once (16 MiB): what big
	 * transfers can pin, whatever max_transfer (mailbox/budget.h). */
	unsigned transfer_memory;
	uint8_t default_access; /* for uids not in rules (WRITE) */
	cogw_access_rule rules[COGW_ACCESS_RULES_MAX];
	size_t n_rules;
} cogw_mailbox_config;

/* A device object of a line's slave (gateway.forward). */
typedef struct cogw_dev_ref {
	uint8_t line; /* index in lines[] */
	uint8_t node;
	uint16_t index;
	uint8_t sub;
} cogw_dev_ref;

/* PDO forwarding by device object (docs/gateway.md "Forwarding device
 * objects"): the value of `from` (in a TPDO of its device) goes to `to` (in
 * an RPDO of its device) through the process image object `image` (sub 0,
 * UNSIGNED64, in every line's OD). */
typedef struct cogw_forward {
	cogw_dev_ref from, to;
	uint16_t image;
} cogw_forward;

#define COGW_FORWARDS_MAX 64u
#define COGW_FORWARD_IMAGE_FIRST 0xBF00u /* "image" when not given: BF00h + n */

typedef struct cogw_config {
	char source[256];    /* file name or "<embedded default>" */
	char state_dir[256]; /* 1010h/1011h storage (/var/lib/cogw) */
	bool mlockall;
	unsigned watchdog_check_ms; /* line check-in period (default 500) */
	cogw_mailbox_config mailbox;
	cogw_line_config lines[COGW_LINES_MAX];
	size_t n_lines;
	/* "file_memory": bytes the files the configuration names may hold
	 * together (64 MiB): every file once, plus each node's concise DCF */
	unsigned file_memory;
	cogw_file_set files;                      /* those files (owned) */
	cogw_forward forwards[COGW_FORWARDS_MAX]; /* gateway.forward */
	size_t n_forwards;
	/* Test hooks (off by default): SIGUSR2 stalls line 0 for stall_ms,
	 * to prove that a stuck line stops the systemd watchdog pings. */
	bool debug_stall_signal;
	unsigned debug_stall_ms;
} cogw_config;

/* The configuration compiled into cogwd (etc/cogw.json at build time). */
extern const char cogw_default_config_json[];
/* Its source name for cogw_config_load_string. Loaded under this name, the
 * files it names (the demo transducer's DCF) come from cogw_default_files,
 * compiled in with it from the .dcf files of etc/: a bare cogwd starts from any working
 * directory. */
#define COGW_DEFAULT_CONFIG_SOURCE "etc/cogw.json (embedded default)"

extern const cogw_embedded_file cogw_default_files[]; /* ends with name NULL */

/* Parse and validate. On error returns -EINVAL (or -ENOENT/-EIO/-ENOMEM
 * for the file) and writes one line "source: path: reason" into err.
 * On success *cfg is complete and owns its ODs (cogw_config_free). */
int cogw_config_load_file(cogw_config *cfg, const char *path, char *err, size_t errlen);
int cogw_config_load_string(cogw_config *cfg, const char *json, const char *source_name, char *err,
			    size_t errlen);
void cogw_config_free(cogw_config *cfg); /* accepts a zeroed config */

/* What a reload may change without restarting (docs/config.md "Reload"):
 * access rules, lease, the heartbeat producer time and consumers, RT
 * settings, and the nodes of a line with a manager (cogw_config_node_diff
 * names what of those needs a restart). Fills `what` with the keys that
 * differ but cannot change at run time, by JSON path:
 * "lines[0].bitrate: needs a restart; mailbox.depth: needs a restart"
 * ("" if none). Returns true if `next` is acceptable as a reload of
 * `cur`. */
bool cogw_config_reload_check(const cogw_config *cur, const cogw_config *next, char *what,
			      size_t whatlen);

/* The explicit "heartbeat_consumers" of a line by node-ID (time in ms, 0 =
 * none), without the 1016h entries of its nodes' heartbeat_ms. Returns
 * how many. */
size_t cogw_config_consumers(const cogw_line_config *l, uint16_t out[128]);

/* The room of 1F22h:id in the OD a line started with (0 = none): what a
 * concise DCF of that node may take at run time. */
uint32_t cogw_node_cdcf_room(const cogw_line_config *started, uint8_t id);

/* A line's "nodes" by node-ID (NULL = not listed). */
void cogw_nodes_by_id(const cogw_line_config *l, const cogw_node *out[128]);

typedef enum cogw_node_change_kind {
	COGW_NODE_ADDED = 1,
	COGW_NODE_CHANGED,
	COGW_NODE_REMOVED,
} cogw_node_change_kind;

typedef struct cogw_node_change {
	uint8_t kind; /* cogw_node_change_kind */
	uint8_t id;
	size_t index;          /* in next->nodes (removed: 0) */
	const cogw_node *node; /* next's entry (removed: the running one) */
} cogw_node_change;

typedef struct cogw_node_diff {
	cogw_node_change change[254]; /* removals first, then in next's order */
	size_t n;
	char what[1024]; /* the keys that need a restart, as reload_check's */
} cogw_node_diff;

/* The nodes of line line_no that a reload adds, changes or removes, from
 * the running ones by node-ID (`cur`: what the line has from the last
 * file it applied; `started`: the configuration the line started with) to
 * `next`'s. Returns false, with `what` naming them, when some of it needs
 * a restart: a node's software_id or program, a concise DCF larger than
 * the room its 1F22h:n got at start-up, or a node list on a line without
 * a manager. */
bool cogw_config_node_diff(const cogw_node *const cur[128], const cogw_line_config *started,
			   const cogw_line_config *next, size_t line_no, cogw_node_diff *out);

#endif /* COGW_APPS_CONFIG_H */
