/* SPDX-License-Identifier: MIT */
/*
 * apps/cosim/cosim.h - the device simulator's internal interfaces.
 *
 * cosim runs one or more simulated CANopen slave nodes on one CAN line,
 * each a full core instance (core/co.h) built from a JSON device file
 * (docs/cosim.md). Everything runs on one thread: main.c owns the event
 * loop (CAN socket, one timerfd, signalfd, control socket) and calls into
 * the nodes with one time value per loop iteration.
 *
 *   device.c  device file -> cosim_device (description + object dictionary)
 *   sim.c     one running node: core instance, signals, loopback, faults,
 *             the send/receive interception, control commands
 *   nv.c      1010h "save" / 1011h "load" and the LSS node-ID, on disk
 *   program.c 1F50h/1F51h/1F56h program download state machine
 *   log.c     the log line and the image CRC-32 (the leaves)
 *   main.c    command line, event loop, local delivery between nodes
 *
 * Calls go down only: main.c -> sim.c -> device.c, program.c, nv.c ->
 * log.c (tests/checks/check_callgraph).
 *
 * Faults are injected here, at the edge of the core (frames dropped,
 * delayed, changed or answered in place of the core), never inside core/:
 * the core under test stays the one the daemon runs.
 */
#ifndef COGW_APPS_COSIM_H
#define COGW_APPS_COSIM_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/co.h"
#include "core/frame.h"
#include "core/od.h"
#include "core/od_image.h"

#define COSIM_NAME_MAX 64
#define COSIM_PDO_MAX 32u /* PDOs per direction in a device file */
#define COSIM_SIGNAL_MAX 32u
#define COSIM_LOOPBACK_MAX 32u
#define COSIM_DELAY_QUEUE 64u /* SDO answers held back by "sdo delay" */
#define COSIM_ERR_MAX 512

/* ---- device description (device.c) ------------------------------------ */

typedef enum cosim_signal_kind {
	COSIM_SIG_CONST = 0,
	COSIM_SIG_RAMP,   /* min -> max over period_ms, then again from min */
	COSIM_SIG_SINE,   /* (min + max) / 2 +- (max - min) / 2 */
	COSIM_SIG_SQUARE, /* min for half a period, max for the other half */
} cosim_signal_kind;

const char *cosim_signal_kind_to_string(cosim_signal_kind k);

typedef struct cosim_signal_desc {
	char name[COSIM_NAME_MAX]; /* "pressure"; "" = unnamed */
	uint16_t index;
	uint8_t sub;
	cosim_signal_kind kind;
	double min, max, value; /* value: const */
	uint32_t period_ms;
	uint32_t update_ms; /* how often the object is refreshed */
	bool notify;        /* trigger event-driven TPDOs on change */
	/* Optional scaling, value = (raw + offset) * span / 100, with offset
	 * and span read from these objects at each update (the transducer's
	 * 2004h:1 zero offset and 2005h:1 span in %). index 0 = none. */
	uint16_t offset_index;
	uint8_t offset_sub;
	uint16_t span_index;
	uint8_t span_sub;
} cosim_signal_desc;

typedef struct cosim_loopback_desc {
	uint16_t from_index; /* an output (RPDO/SDO written) */
	uint8_t from_sub;
	uint16_t to_index; /* the input it is echoed into */
	uint8_t to_sub;
} cosim_loopback_desc;

/* A COB-ID whose default is "base + node-ID" (CiA 301 predefined
 * connection set, or a PDO with "add_node_id"): moved along when LSS
 * changes the node-ID, invalid (bit 31) while the node is unconfigured. */
typedef struct cosim_rel_cob {
	uint16_t index;
	uint8_t sub;
	uint32_t base; /* value with node-ID 0 (flag bits included) */
} cosim_rel_cob;

#define COSIM_REL_COB_MAX (4u + 2u * COSIM_PDO_MAX)

/* The program download objects of CiA 302-3 (device file "program"). */
typedef struct cosim_program_desc {
	bool enabled;
	uint32_t flash_max; /* capacity of 1F50h:1 (the simulated flash) */
	bool refuse;        /* refuse every image on start (a device that
	                       * rejects the firmware it is given) */
	bool factory;       /* the flash starts with the factory image (true)
	                       * or erased (false) */
} cosim_program_desc;

/* Program state machine (1F51h:1 read value). */
typedef enum cosim_program_state {
	COSIM_PROG_STOPPED = 0, /* an image, not running */
	COSIM_PROG_RUNNING = 1,
	COSIM_PROG_CLEARED = 3, /* flash erased: 1F50h:1 may be written */
} cosim_program_state;

typedef struct cosim_program {
	co_od *od;
	const cosim_program_desc *desc;
	uint8_t state;      /* cosim_program_state */
	uint32_t image_len; /* bytes in the flash */
	uint32_t refused;   /* starts refused */
	bool quiet;
	uint8_t node_id; /* for log lines */
} cosim_program;

/* Hook 1F50h:1/1F51h:1 (built by the device) into the state machine.
 * Power-on state from the flash (factory image, stored image or none):
 * a good image RUNNING with 1F56h:1 = its CRC, a bad one STOPPED, none
 * CLEARED. Then:
 * - 1F50h:1 (program data) may be written only while CLEARED (else
 *   0x08000022); a complete write leaves the program STOPPED;
 * - 1F51h:1 write 0 = stop (RUNNING -> STOPPED), 1 = start, 2 = reset
 *   (stop, start), 3 = clear (STOPPED -> CLEARED, 1F56h:1 = 0; refused
 *   while RUNNING with 0x08000022); other values 0x06090030;
 * - start checks the image: at least 5 bytes, the last 4 the CRC-32
 *   (IEEE 802.3, little-endian) of the others; a bad image, no image or
 *   "refuse" -> 0x08000020 and the program stays STOPPED; a good one
 *   runs and 1F56h:1 (application software identification) = its CRC. */
int cosim_program_attach(cosim_program *p, co_od *od, const cosim_program_desc *desc,
			 uint8_t node_id, bool quiet);
/* Make the flash, 1F51h:1 and 1F56h:1 as they are now their defaults, so
 * that NMT resets keep them (flash is not a parameter); called after every
 * change, and by the owner after something rewrote the defaults (1011h). */
void cosim_program_pin(cosim_program *p);
/* CRC-32 (IEEE 802.3, reflected, init and final xor FFFFFFFFh). */
uint32_t cosim_crc32(const uint8_t *data, size_t len);

typedef struct cosim_device {
	char file[256]; /* for messages */
	char name[COSIM_NAME_MAX];
	uint8_t node_id; /* after --node-id; 255 = unconfigured */
	co_od *od;       /* owned */
	bool lss_enabled;
	bool lss_constant_id;
	uint16_t lss_bit_timing_mask; /* bit i = CiA table 0 index i allowed;
	                               * 0 = the core's default (all) */
	bool loopback_enabled;
	unsigned n_signals;
	cosim_signal_desc signals[COSIM_SIGNAL_MAX];
	unsigned n_loopback;
	cosim_loopback_desc loopback[COSIM_LOOPBACK_MAX];
	unsigned n_rel;
	cosim_rel_cob rel[COSIM_REL_COB_MAX];
	cosim_program_desc program;
} cosim_device;

/* Set every node-relative COB-ID (dev->rel) for node_id, default and
 * current value; node_id 255 marks them invalid. */
void cosim_device_rebase(cosim_device *dev, co_od *od, uint8_t node_id);

/* Per-device command-line overrides (--node-id, --serial after --device). */
typedef struct cosim_device_opts {
	int node_id;    /* -1 = from the file */
	int64_t serial; /* -1 = from the file */
} cosim_device_opts;

/* Load and check a device file and build its OD. Errors: -EINVAL with
 * "file: json.path: reason" in err, -ENOENT/-EIO for the file itself,
 * -ENOMEM. */
int cosim_device_load(cosim_device *dev, const char *path, const cosim_device_opts *opts, char *err,
		      size_t errlen);
/* Same from a string (tests, fuzzing); `file` names it in messages. */
int cosim_device_load_string(cosim_device *dev, const char *file, const char *json,
			     const cosim_device_opts *opts, char *err, size_t errlen);
void cosim_device_free(cosim_device *dev); /* accepts a zeroed device */

/* "0x2003:00" (sub optional, default 0) -> index/sub. */
int cosim_parse_object(const char *s, uint16_t *index, uint8_t *sub);

/* ---- faults ------------------------------------------------------------- */

typedef struct cosim_faults {
	bool silent;              /* cable pulled: nothing out, nothing in */
	bool hb_stop;             /* heartbeats (not boot-ups) are dropped */
	bool sdo_silent;          /* SDO server answers are dropped */
	uint32_t sdo_abort;       /* != 0: every SDO initiate is answered with it */
	uint16_t sdo_abort_index; /* restrict sdo_abort to one object
	                           * (0 = every object) */
	uint8_t sdo_abort_sub;
	bool sdo_abort_any_sub;
	uint32_t sdo_delay_ms; /* SDO answers go out this much later */
	bool pdo_badlen;       /* TPDOs go out one byte short (or one long if 0) */
	bool sdo_lenient;      /* accept printed-sheet frames: a too small size
	                    * indicated for a numeric object, and the
	                    * reversed "save" signature (docs/cosim.md) */
} cosim_faults;

/* ---- one running node (sim.c) ------------------------------------------ */

typedef struct cosim_node cosim_node;

/* How a node's frames leave the process: main.c's port and local bus. */
typedef int (*cosim_out_fn)(void *ctx, cosim_node *from, const co_frame *f, uint64_t now_us);

typedef struct cosim_node_config {
	cosim_device *dev;  /* ownership passes to the node */
	const char *nv_dir; /* NULL = nothing persists */
	const char *nv_key; /* file name stem in nv_dir */
	cosim_faults faults;
	bool autostart; /* enter OPERATIONAL after boot-up by itself */
	bool quiet;
	uint32_t sdo_timeout_ms; /* SDO server, per frame; 0 = core default
	                          * (1000 ms) */
	cosim_out_fn out;
	void *out_ctx;
	uint64_t now_us; /* start time (signals count from here) */
} cosim_node_config;

int cosim_node_create(cosim_node **out, const cosim_node_config *cfg, char *err, size_t errlen);
void cosim_node_destroy(cosim_node *n); /* accepts NULL */

/* A frame from the bus (or from another local node). */
void cosim_node_recv(cosim_node *n, const co_frame *f, uint64_t now_us);
/* Run timers, signals, the delay queue. Returns the next deadline. */
uint64_t cosim_node_tick(cosim_node *n, uint64_t now_us);
uint64_t cosim_node_next_deadline(const cosim_node *n);

/* The node-ID given at start (names the node in commands and logs). */
uint8_t cosim_node_config_id(const cosim_node *n);
co_node *cosim_node_core(const cosim_node *n);
cosim_faults *cosim_node_faults(cosim_node *n);

/*
 * Apply one control command (docs/cosim.md) to this node. Returns 0 and
 * a short answer in reply, or -EINVAL with the reason in reply.
 */
int cosim_node_command(cosim_node *n, const char *line, uint64_t now_us, char *reply,
		       size_t replylen);

/* Log one line on stderr unless quiet ("cosim: node 1: ..."). */
void cosim_log(bool quiet, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* ---- persistence (nv.c) ----------------------------------------------- */

/* Parts of the OD that 1010h/1011h sub-indexes name (CiA 301 §7.5.2.13). */
#define COSIM_NV_COMM CO_OD_IMAGE_COMM /* 1000h..1FFFh */
#define COSIM_NV_APP CO_OD_IMAGE_APP   /* 2000h..FFFFh */

/* Write the persistent entries of `parts` to <dir>/<key>.comm / .app,
 * atomically (temp file + rename). 0 or -errno. */
int cosim_nv_save(const co_od *od, const char *dir, const char *key, unsigned parts);
/* Load whatever is stored; each value becomes default and current value.
 * Bad records are skipped and counted in *skipped. 0 (also when no file
 * exists; *loaded = 0) or -errno. */
int cosim_nv_load(co_od *od, const char *dir, const char *key, unsigned *loaded, unsigned *skipped);
/* Delete the stored parts. */
int cosim_nv_erase(const char *dir, const char *key, unsigned parts);
/* LSS: the persistent node-ID (<key>.lss). load: -ENOENT if none. */
int cosim_nv_save_node_id(const char *dir, const char *key, uint8_t node_id);
int cosim_nv_load_node_id(const char *dir, const char *key, uint8_t *node_id);

#endif /* COGW_APPS_COSIM_H */
