/* SPDX-License-Identifier: MIT */
/*
 * core/cfgmgr.h - the CiA 302-3 configuration manager's work on one slave:
 * restore its defaults if asked, verify its configuration, download a
 * concise DCF entry by entry, then record and store the result. One job
 * per node being configured; a core/fsm.h machine, I/O-free.
 *
 * Steps (each a state, see co_cfgmgr_state_to_string):
 *   1. restore (1F81h bit 7 with 1F8Ah:n != 0): write "load" to the
 *      slave's 1011h:sub, reset it - communication for sub 2, application
 *      (reset node) otherwise - and wait for its boot-up;
 *   2. verify (1F26h/1F27h given): read the slave's 1020h:1 and 1020h:2;
 *      both equal to the expected date/time -> done, nothing downloaded
 *      (outcome SKIPPED); a difference or an abort (1020h not supported)
 *      -> download;
 *   3. download: every entry of the concise DCF in order, one SDO download
 *      each, mode AUTO (expedited up to 4 bytes, block from the SDO
 *      client's threshold on, segmented between);
 *   4. after a download with verify: write 1020h:1 and 1020h:2;
 *   5. store (config says so): write "save" to 1010h:1.
 * The first abort stops the job: outcome FAILED, status 'J', with the
 * entry number (1-based; 0 for a step outside the concise DCF), the
 * index:sub and the abort code. A boot-up that does not come after the
 * restore reset fails with 1011h:sub and 0x05040000 (timed out).
 *
 * SDO requests go to the channel the caller holds (the CiA 302-2 boot
 * process keeps one per booting node) or, with channel < 0, to the node's
 * SDO client pool. Completions come through the per-request
 * confirmations (sdo_client_req.con); boot-ups through
 * co_cfgmgr_on_event(). The caller calls co_cfgmgr_tick() at or after
 * co_cfgmgr_next_deadline_us() (only the boot-up wait has a timer of its
 * own; SDO timeouts are the SDO client's).
 *
 * The job object is the caller's (embed it, no allocation); the concise
 * DCF buffer must stay valid until the job ends. Owning thread only.
 */
#ifndef COGW_CORE_CFGMGR_H
#define COGW_CORE_CFGMGR_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/cdcf.h"
#include "core/co.h"
#include "core/event.h"
#include "core/fsm.h"

#define CO_CFGMGR_BOOTUP_WAIT_MS 5000u

typedef enum co_cfgmgr_state {
	CO_CFGMGR_IDLE = 0,
	CO_CFGMGR_RESTORE_LOAD,  /* write "load" to 1011h:sub */
	CO_CFGMGR_RESTORE_RESET, /* NMT reset sent, waiting for the boot-up */
	CO_CFGMGR_VERIFY_DATE,   /* read 1020h:1 */
	CO_CFGMGR_VERIFY_TIME,   /* read 1020h:2 */
	CO_CFGMGR_DOWNLOAD,      /* the concise DCF, entry by entry */
	CO_CFGMGR_WRITE_DATE,    /* write 1020h:1 */
	CO_CFGMGR_WRITE_TIME,    /* write 1020h:2 */
	CO_CFGMGR_STORE,         /* write "save" to 1010h:1 */
	CO_CFGMGR_DONE,
	CO_CFGMGR_FAILED,
	CO_CFGMGR_N_STATES
} co_cfgmgr_state;

const char *co_cfgmgr_state_to_string(int state);

typedef enum co_cfgmgr_outcome {
	CO_CFGMGR_CONFIGURED = 0, /* downloaded (and recorded/stored) */
	CO_CFGMGR_SKIPPED,        /* 1020h matched: nothing downloaded */
	CO_CFGMGR_FAILED_J,       /* an abort stopped it: status J */
	CO_CFGMGR_CANCELLED,      /* co_cfgmgr_cancel */
} co_cfgmgr_outcome;

const char *co_cfgmgr_outcome_to_string(int outcome);

typedef struct co_cfgmgr_result {
	uint8_t node_id;
	uint8_t outcome; /* co_cfgmgr_outcome */
	char status;     /* 'J' when FAILED_J, else 0 */
	uint32_t entry;  /* failing entry, 1-based; 0 = not a cDCF entry */
	uint16_t index;  /* failing object */
	uint8_t sub;
	uint32_t abort;   /* CiA abort code of the failure */
	uint32_t written; /* concise DCF entries written */
	bool restored;    /* the restore step ran */
} co_cfgmgr_result;

typedef void (*co_cfgmgr_done_fn)(void *ctx, const co_cfgmgr_result *r, uint64_t now_us);

typedef struct co_cfgmgr_params {
	uint8_t node_id;     /* slave 1..127 */
	const uint8_t *cdcf; /* concise DCF (NULL/0 = nothing to write) */
	size_t cdcf_len;
	bool verify;             /* compare/record 1020h with date/time */
	uint32_t date;           /* 1F26h:node, days since 1984-01-01 */
	uint32_t time;           /* 1F27h:node, ms after midnight */
	bool store;              /* "save" to 1010h:1 after a download */
	uint8_t restore_sub;     /* 1F8Ah:node: 1011h sub-index, 0 = none */
	uint32_t bootup_wait_ms; /* after the restore reset (0 = 5000) */
	int channel;             /* SDO client channel, < 0 = the pool */
	uint32_t sdo_timeout_ms; /* per frame, 0 = the SDO client's */
	co_cfgmgr_done_fn done;  /* called once when the job ends */
	void *done_ctx;
} co_cfgmgr_params;

typedef struct co_cfgmgr {
	co_fsm fsm;
	co_node *node;
	co_cfgmgr_params p;
	co_cdcf_iter it;
	co_cdcf_entry cur; /* entry being written */
	uint64_t tag;      /* tag of the request in flight, 0 = none */
	uint32_t seq;
	uint64_t deadline_us; /* boot-up wait; UINT64_MAX = none */
	uint8_t rd[4];        /* 1020h reads */
	uint8_t wr[4];        /* 1020h / 1010h / 1011h writes */
	co_cfgmgr_result res;
} co_cfgmgr;

/*
 * Start a job (idle or ended before). The concise DCF is checked first:
 * -EINVAL for a malformed one (nothing is sent), for a bad node id or
 * restore sub-index, -EBUSY if the job is running. The first request goes
 * out now; the outcome arrives through p->done, never from inside this
 * call.
 */
int co_cfgmgr_start(co_cfgmgr *job, co_node *node, const co_cfgmgr_params *p, uint64_t now_us);
/* Every core event of the node (the boot-up of the restore step). */
void co_cfgmgr_on_event(co_cfgmgr *job, const co_event *ev, uint64_t now_us);
/* Run the job's timer; returns its next deadline (CO_NO_DEADLINE = none). */
uint64_t co_cfgmgr_tick(co_cfgmgr *job, uint64_t now_us);
uint64_t co_cfgmgr_next_deadline_us(const co_cfgmgr *job);
/* Stop a running job: the request in flight is aborted (0x08000000) and
 * done() reports CANCELLED. 0 or -ENOENT (not running). Call it before
 * the job's memory goes away. */
int co_cfgmgr_cancel(co_cfgmgr *job, uint64_t now_us);
bool co_cfgmgr_running(const co_cfgmgr *job);
static inline int co_cfgmgr_state_of(const co_cfgmgr *job)
{
	return co_fsm_state_of(&job->fsm);
}

/* ======================================================================
 * The configuration manager of a line: the objects and one job per node
 * ====================================================================== */

/*
 * Objects (CiA 302-3), in the manager's own OD:
 *   1F22h:n  concise DCF of node n (DOMAIN, rw; written by the
 *            configuration at start-up, or over SDO / the mailbox)
 *   1F26h:n  expected configuration date (UNSIGNED32, rw, 0 = none)
 *   1F27h:n  expected configuration time (UNSIGNED32, rw, 0 = none)
 *   1F8Ah:n  restore configuration: 1011h sub-index to "load" before the
 *            configuration when 1F81h:n bit 7 is set (UNSIGNED8, rw)
 * co_od_add_cfgmgr_node() makes node n configurable: it creates the four
 * arrays on first use (sub 0 = 127; 1F26h/1F27h/1F8Ah with all 127 subs)
 * and 1F22h:n with room for cdcf_cap bytes (the capacity is allocated:
 * only nodes that can be configured get a 1F22h sub-index). 0, -EINVAL,
 * -ENOMEM; an existing 1F22h:n is kept (0).
 */
#define CO_CFGMGR_IDX_CDCF 0x1F22u
#define CO_CFGMGR_IDX_DATE 0x1F26u
#define CO_CFGMGR_IDX_TIME 0x1F27u
#define CO_CFGMGR_IDX_RESTORE 0x1F8Au
#define CO_CFGMGR_F81_RESTORE 0x80u /* 1F81h:n bit 7 */
int co_od_add_cfgmgr_node(co_od *od, uint8_t node_id, uint32_t cdcf_cap);

typedef struct co_cfgmgr_line {
	co_node *node;
	co_cfgmgr job[127];      /* job[n - 1] configures node n */
	bool store[128];         /* save (1010h:1) after a download */
	int channel;             /* SDO channel for every job, < 0 = pool */
	uint32_t sdo_timeout_ms; /* 0 = the SDO client's */
	co_cfgmgr_done_fn done;  /* the owner's report (e.g. to the 302-2
	                          * boot process: co_manager_configure_done) */
	void *done_ctx;
} co_cfgmgr_line;

/*
 * Bind to a node whose OD has the objects above. Installs a check on
 * 1F22h:n: a write while node n is being configured is refused
 * (0x08000022), one that is not a concise DCF too (0x06090030) when the
 * value is seen whole. Owning thread; no allocation.
 */
void co_cfgmgr_line_init(co_cfgmgr_line *l, co_node *node, co_cfgmgr_done_fn done, void *done_ctx);
/*
 * The 302-2 "configure" step of node n (the signature of the manager's
 * configure hook; ctx = the line). Reads 1F22h:n, 1F26h:n, 1F27h:n,
 * 1F81h:n bit 7 and 1F8Ah:n now. Returns 0 when there is nothing to do
 * (no concise DCF, no date/time, no restore), 1 when a job started (done()
 * reports it), -EINVAL for a 1F22h:n that is not a concise DCF, -EBUSY if
 * node n's job is running.
 */
int co_cfgmgr_line_configure(void *ctx, uint8_t node_id, uint64_t now_us);
void co_cfgmgr_line_on_event(co_cfgmgr_line *l, const co_event *ev, uint64_t now_us);
uint64_t co_cfgmgr_line_tick(co_cfgmgr_line *l, uint64_t now_us);
uint64_t co_cfgmgr_line_next_deadline_us(const co_cfgmgr_line *l);
/* Cancel every running job (their done() reports CANCELLED). */
void co_cfgmgr_line_cancel_all(co_cfgmgr_line *l, uint64_t now_us);

#endif /* COGW_CORE_CFGMGR_H */
