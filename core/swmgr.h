/* SPDX-License-Identifier: MIT */
/*
 * core/swmgr.h - the CiA 302-3 software manager's work on one slave:
 * check its application software identification and, when an update is
 * allowed, replace its program. One job per node; a core/fsm.h machine,
 * I/O-free (the image is read through a source callback).
 *
 * Steps (each a state, see co_swmgr_state_to_string):
 *   0. program: read the slave's program control 1F51h:1 (CiA 302-3: 1
 *      = the program runs, 0 = stopped, 3 = no program, e.g. a flash
 *      cleared by a download that was cut short). A slave without the
 *      object (any abort) has no program control: go on. A program that
 *      does not run needs an update whatever 1F56h:1 says (H when not
 *      allowed, G without an image). A job that only looks (check_id
 *      false: 1F81h:n bit 5 clear) ends here, always UNCHANGED, with the
 *      state in the result for its owner to report;
 *   1. check: read the slave's 1F56h:1 (application software
 *      identification); equal to the expected one (1F55h:n) -> done,
 *      nothing downloaded (outcome UNCHANGED). A difference without
 *      update permission (1F81h:n bit 6) -> status H. A forced (manual)
 *      update skips the check;
 *   2. stop the program: write 0 to 1F51h:1;
 *   3. clear it: write 3 to 1F51h:1;
 *   4. download the image to 1F50h:1 by SDO block transfer, the bytes
 *      taken from the source callback; progress reported every
 *      progress_step bytes and at the end;
 *   5. start the program: write 1 to 1F51h:1;
 *   6. verify: read 1F56h:1 again; it must now equal the expected
 *      identification (not compared when none is expected: 0).
 * Status letters (CiA 302-2 boot status): G = the program download
 * objects are not configured (1F55h:n is 0, or an update is needed and
 * there is no image for the node); H = an update is needed but not
 * allowed; I = the update failed: any abort in steps 1-6 (the result
 * names the object and the abort code), or the identification read
 * after the start still differs (abort 0, found = the value read).
 *
 * SDO requests go to the channel given or, with channel < 0, to the
 * node's SDO client pool; completions come through the per-request
 * confirmations. The job has no timer of its own (SDO timeouts are the
 * SDO client's). The job object is the caller's (embed it, no
 * allocation); the source must stay valid until the job ends. Owning
 * thread only.
 */
#ifndef COGW_CORE_SWMGR_H
#define COGW_CORE_SWMGR_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/co.h"
#include "core/event.h"
#include "core/fsm.h"

#define CO_SWMGR_IDX_DATA 0x1F50u     /* slave: program data (DOMAIN) */
#define CO_SWMGR_IDX_CONTROL 0x1F51u  /* slave: program control (U8) */
#define CO_SWMGR_IDX_EXPECTED 0x1F55u /* manager: expected software id */
#define CO_SWMGR_IDX_ID 0x1F56u       /* slave: software identification */
#define CO_SWMGR_IDX_IMAGE 0x1F58u    /* manager: program image of node n */
#define CO_SWMGR_F81_CHECK 0x20u      /* 1F81h:n bit 5: check software */
#define CO_SWMGR_F81_UPDATE 0x40u     /* 1F81h:n bit 6: update allowed */
#define CO_SWMGR_PROGRESS_STEP 4096u

/* 1F51h values (CiA 302-3) */
enum co_swmgr_control {
	CO_SWMGR_CTL_STOP = 0,
	CO_SWMGR_CTL_START = 1,
	CO_SWMGR_CTL_RESET = 2,
	CO_SWMGR_CTL_CLEAR = 3,
};

typedef enum co_swmgr_state {
	CO_SWMGR_IDLE = 0,
	CO_SWMGR_PROGRAM,  /* read 1F51h:1 */
	CO_SWMGR_CHECK,    /* read 1F56h:1 */
	CO_SWMGR_STOP,     /* 1F51h:1 = 0 */
	CO_SWMGR_CLEAR,    /* 1F51h:1 = 3 */
	CO_SWMGR_DOWNLOAD, /* image -> 1F50h:1, block transfer */
	CO_SWMGR_START,    /* 1F51h:1 = 1 */
	CO_SWMGR_VERIFY,   /* read 1F56h:1 again */
	CO_SWMGR_DONE,
	CO_SWMGR_FAILED,
	CO_SWMGR_N_STATES
} co_swmgr_state;

const char *co_swmgr_state_to_string(int state);

typedef enum co_swmgr_outcome {
	CO_SWMGR_UNCHANGED = 0, /* 1F56h:1 matched: nothing downloaded */
	CO_SWMGR_UPDATED,       /* downloaded, started and verified */
	CO_SWMGR_FAILED_STATUS, /* status G, H or I */
	CO_SWMGR_CANCELLED,     /* co_swmgr_cancel */
} co_swmgr_outcome;

const char *co_swmgr_outcome_to_string(int outcome);

typedef struct co_swmgr_result {
	uint8_t node_id;
	uint8_t outcome; /* co_swmgr_outcome */
	char status;     /* 'G', 'H', 'I' when FAILED_STATUS, else 0 */
	uint8_t step;    /* co_swmgr_state of the failure (0 = none) */
	uint16_t index;  /* object of the failure (0 = none) */
	uint8_t sub;
	uint32_t abort;    /* CiA abort code of the failure (0 = none) */
	uint32_t expected; /* 1F55h:n */
	uint32_t found;    /* last 1F56h:1 read from the slave */
	uint32_t bytes;    /* image bytes sent */
	bool downloaded;   /* steps 2-6 ran */
	uint8_t mode;      /* sdo_mode the image went by: block, or segmented
	                    * when the device refused block (SDO client
	                    * fallback, core/sdo_client.h); 0 = not sent */
	uint8_t program;   /* 1F51h:1 read in step 0, CO_SWMGR_PROGRAM_UNKNOWN
	                    * when not read (forced update, no such object) */
	bool look_only;    /* the job only read 1F51h:1 (params.look_only) */
} co_swmgr_result;

#define CO_SWMGR_PROGRAM_UNKNOWN 0xFFu
/* 1F51h:1 read values (CiA 302-3) */
enum co_swmgr_program_state {
	CO_SWMGR_PROG_STOPPED = 0,
	CO_SWMGR_PROG_STARTED = 1,
	CO_SWMGR_PROG_NONE = 3, /* no program available */
};

/* "stopped", "started", "no program", "unknown" (not read), else "?" */
const char *co_swmgr_program_to_string(uint8_t program);

/* The slave's program was read and does not run (1F51h:1 not "started"). */
bool co_swmgr_program_down(const co_swmgr_result *r);

/* What the boot's "check software" event names (co_manager_software_done):
 * 1F51h:1 and the program state when that was the finding (a look-only
 * job that saw a program not running, or a failure on it), else the
 * object of the failure and the 1F56h:1 read (0:0 when nothing failed). */
void co_swmgr_result_finding(const co_swmgr_result *r, uint16_t *index, uint8_t *sub,
			     uint32_t *value);

typedef void (*co_swmgr_done_fn)(void *ctx, const co_swmgr_result *r, uint64_t now_us);
/* Progress of the download: sent of total bytes (total = image size). */
typedef void (*co_swmgr_progress_fn)(void *ctx, uint8_t node_id, uint32_t sent, uint32_t total,
				     uint64_t now_us);

/* Where the program images come from (1F58h:n; e.g. a file per node the
 * owner has opened). size: the image size of node n, 0 = none. read:
 * copy up to len bytes at offset (sequential) into buf; returns the count
 * copied or a negative errno (the transfer is aborted, status I). */
typedef struct co_swmgr_source {
	uint32_t (*size)(void *ctx, uint8_t node_id);
	int (*read)(void *ctx, uint8_t node_id, uint32_t offset, uint8_t *buf, uint32_t len);
	void *ctx;
} co_swmgr_source;

typedef struct co_swmgr_params {
	uint8_t node_id;        /* slave 1..127 */
	uint32_t expected;      /* 1F55h:n; 0 = none (G unless forced) */
	bool update_allowed;    /* 1F81h:n bit 6 */
	bool force;             /* manual update: no check, always download */
	bool look_only;         /* read 1F51h:1 alone, never fail (1F81h:n
	                         * bit 5 clear: software not checked) */
	co_swmgr_source source; /* image of the node (size 0 = none) */
	uint32_t progress_step; /* bytes between progress reports (0 = 4096) */
	co_swmgr_progress_fn progress;
	void *progress_ctx;
	int channel;             /* SDO client channel, < 0 = the pool */
	uint32_t sdo_timeout_ms; /* per frame, 0 = the SDO client's */
	co_swmgr_done_fn done;   /* called once when the job ends */
	void *done_ctx;
} co_swmgr_params;

typedef struct co_swmgr {
	co_fsm fsm;
	co_node *node;
	co_swmgr_params p;
	uint32_t image_size;
	uint32_t next_progress; /* byte count of the next progress report */
	uint64_t tag;           /* request in flight, 0 = none */
	uint32_t seq;
	uint8_t rd[4];
	uint8_t wr[4];
	bool started; /* co_swmgr_start returned 0: done() reports */
	co_swmgr_result res;
} co_swmgr;

/*
 * Start a job (idle or ended before): -EINVAL for a bad node id, channel
 * or source (read without size), -EBUSY if the job is running, -ENOENT
 * for status G found at once (1F55h:n is 0 and the update is not forced;
 * a forced update without an image), -EAGAIN when the first request
 * cannot be queued. After 0 the outcome arrives through p->done, never
 * from inside this call.
 */
int co_swmgr_start(co_swmgr *job, co_node *node, const co_swmgr_params *p, uint64_t now_us);
/* Stop a running job: the request in flight is aborted (0x08000000) and
 * done() reports CANCELLED. 0 or -ENOENT. */
int co_swmgr_cancel(co_swmgr *job, uint64_t now_us);
bool co_swmgr_running(const co_swmgr *job);
static inline int co_swmgr_state_of(const co_swmgr *job)
{
	return co_fsm_state_of(&job->fsm);
}

/* ======================================================================
 * The software manager of a line: 1F55h and one job per node
 * ====================================================================== */

/* Add 1F55h (ARRAY of 127 UNSIGNED32 rw, 0 = no expected software) to the
 * manager's OD unless present. 0, -ENOMEM. */
int co_od_add_swmgr_defaults(co_od *od);

typedef struct co_swmgr_line {
	co_node *node;
	co_swmgr job[127];       /* job[n - 1] works on node n */
	co_swmgr_source source;  /* the images (1F58h) */
	int channel;             /* SDO channel for every job, < 0 = pool */
	uint32_t sdo_timeout_ms; /* 0 = the SDO client's */
	co_swmgr_progress_fn progress;
	void *progress_ctx;
	co_swmgr_done_fn done; /* e.g. to co_manager_software_done */
	void *done_ctx;
} co_swmgr_line;

void co_swmgr_line_init(co_swmgr_line *l, co_node *node, const co_swmgr_source *source,
			co_swmgr_done_fn done, void *done_ctx);
/*
 * The 302-2 "check software" step of node n (the signature of the
 * manager's software hook; ctx = the line). Reads 1F81h:n bits 5/6 and
 * 1F55h:n now. With bit 5 clear the software is not checked, but the
 * program state (1F51h:1) is still read (a look-only job, which never
 * fails: the owner reports a program that does not run). Returns 1 when
 * a job started (done() reports it), -ENOENT for status G found at once
 * (1F55h:n is 0), -EBUSY if node n's job is running, -EAGAIN (no SDO
 * request could be queued), -EINVAL for a bad node.
 */
int co_swmgr_line_check(void *ctx, uint8_t node_id, uint64_t now_us);
/* A manual update of node n (cogwctl program, the mailbox's MGR_PROGRAM):
 * no check; stop, clear, download the image, start, and verify against
 * `expected`, or 1F55h:n when expected is 0 (nothing compared when both
 * are 0). image: where the bytes come from (NULL = the line's source, the
 * configured 1F58h:n); it must stay valid until done() reports. Progress
 * and done() go to the line's callbacks. 0 (done() reports), -ENOENT (no
 * image), -EBUSY (node n's job is running), -EINVAL, -EAGAIN. */
int co_swmgr_line_program(co_swmgr_line *l, uint8_t node_id, const co_swmgr_source *image,
			  uint32_t expected, uint64_t now_us);
void co_swmgr_line_cancel_all(co_swmgr_line *l, uint64_t now_us);

#endif /* COGW_CORE_SWMGR_H */
