/* SPDX-License-Identifier: MIT */
/*
 * core/sdo_client_int.h - what the files of the SDO client share (the
 * public API is core/sdo_client.h). Include it from core/sdo_client*.c only.
 *
 * The files, top to bottom (a file calls only the files below it):
 *   sdo_client.c       the channel machine (its table, the idle, start
 *                      failed and leased states), frames in (cli_rx, with
 *                      the filter of late frames), submit and cancel, the
 *                      service ops (init, tick, NMT)
 *   sdo_client_pool.c  the pool FIFO shared by the channels, the gate
 *                      (sdo_client_set_gate) and the raw leases (CiA 302-7
 *                      relay): who may start what, and when
 *   sdo_client_xfer.c  the transfers: starting one on a channel, the
 *                      expedited, segmented and block machines' states,
 *                      their timeout and the fall-back from block
 */
#ifndef COGW_CORE_SDO_CLIENT_INT_H
#define COGW_CORE_SDO_CLIENT_INT_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co_internal.h"
#include "core/fsm.h"
#include "core/sdo_block.h"
#include "core/sdo_client.h"

#define SUB_BLOCK_BYTES (SDO_BLK_MAX_SEQ * SDO_SEG_DATA) /* 889 */
#define UNKNOWN_SIZE UINT32_MAX

enum cli_state {
	CS_IDLE,
	CS_DN_INIT,      /* initiate download sent */
	CS_DN_SEG,       /* download segment sent */
	CS_UP_INIT,      /* initiate upload sent */
	CS_UP_SEG,       /* upload segment request sent */
	CS_BLK_DN_INIT,  /* block download initiate sent */
	CS_BLK_DN_ACK,   /* sub-block sent, waiting for the ack */
	CS_BLK_DN_END,   /* end sent */
	CS_BLK_UP_INIT,  /* block upload initiate sent */
	CS_BLK_UP_SUB,   /* receiving sub-block segments */
	CS_BLK_UP_END,   /* last sub-block acked, waiting for the end */
	CS_START_FAILED, /* could not start: completes at the next tick with
	                  * start_abort (never inside the submitting call) */
	CS_LEASED,       /* lent out raw (CiA 302-7 relay): frames go to lease_fn */
	CS_COUNT
};

struct cli_chan {
	struct sdo_client *cli;
	uint8_t num;
	co_fsm fsm;          /* state: enum cli_state (cli_states[]) */
	bool done_pending;   /* the request ended: idle's on_enter confirms */
	uint32_t done_abort; /* ... with this abort code (0 = success) */
	int rx_handle;
	uint64_t deadline;
	uint64_t timeout_us;

	/* queue: ring of cfg.sdo_client_queue_len waiting requests */
	sdo_client_req *q;
	uint16_t q_head;
	uint16_t q_len;

	sdo_client_req cur; /* the running request (valid if state != IDLE) */
	uint32_t cob_req;
	uint32_t cob_resp;
	uint8_t mode;
	bool fell_back;
	uint8_t toggle;
	uint32_t offset;      /* bytes confirmed (download) / delivered (upload) */
	uint32_t total;       /* download: size; upload: indicated or UNKNOWN */
	uint32_t read_off;    /* download: bytes taken from the source */
	uint32_t start_abort; /* CS_START_FAILED: the abort to report */
	bool answered;        /* a frame of the server for this request came */

	/* block */
	struct sdo_blk_rx brx; /* upload: sequence, duplicates, CRC */
	struct sdo_blk_tx btx; /* download: sub-block, CRC */
	bool pend_valid;       /* upload: held-back segment (its length is only
	                    * known at the end request) */
	uint8_t pend[SDO_SEG_DATA];
	uint32_t sub_len; /* download: bytes in sub_buf */
	uint8_t sub_buf[SUB_BLOCK_BYTES];

	sdo_client_raw_fn lease_fn; /* CS_LEASED */
	void *lease_arg;
	/* The gate does not offer it (sdo_client_set_gate): the node's own
	 * requests hold it, or a lease bound on it by sdo_client_lease_channel
	 * does; given back (FREE_CHANNEL) once it is idle with nothing queued. */
	bool gated_out;

	co_od_entry *od_cob[2]; /* 1280h+n sub 1/2 */
	co_od_entry *od_node;   /* sub 3 */

	/* `ended`: the last transfer this channel ended with its own abort
	 * frame (cancel, timeout, protocol error). The server may have sent
	 * more frames of it before it saw the abort; the next transfer to
	 * the same server (on any channel) takes it as its `filter` and
	 * ignores those frames until its own first answer arrives (see
	 * is_stale()). Also the last transfer it completed successfully
	 * (`answered`): another answer to that request, arriving within the
	 * timeout while the channel is idle or before the next transfer's
	 * first answer, comes from a second device on the server's node-ID
	 * (CO_EV_SDO_CLIENT_SECOND_ANSWER). */
	struct stale_xfer {
		bool valid;
		bool answered; /* it ended with the server's answer */
		/* the server had answered its initiate: what may still come
		 * are frames of its data phase, which is_stale() tells apart
		 * from the next transfer's answers */
		bool init_answered;
		bool upload;
		uint8_t mode;
		uint16_t index;
		uint8_t sub;
		uint32_t cob_resp;
		uint64_t at_us; /* when it ended (answered, or our abort) */
	} ended, filter;
};

struct sdo_client {
	co_node *node;
	uint8_t n;
	/* pool: ring of cfg.sdo_client_pool_len requests waiting for any
	 * channel */
	sdo_client_req *pool;
	uint16_t pool_head;
	uint16_t pool_len;
	/* the second user of the pool (sdo_client_set_gate) */
	sdo_client_gate_fn gate;
	void *gate_ctx;
	uint64_t srv_held[2]; /* servers (node-IDs) taken from the gate */
	uint64_t retry_us;    /* a refused request is tried again then */
	struct cli_chan ch[];
};

/* ---- helpers ------------------------------------------------------------ */

static inline co_node *node_of(const struct cli_chan *ch)
{
	return ch->cli->node;
}

static inline int state_of(const struct cli_chan *ch)
{
	return co_fsm_state_of(&ch->fsm);
}

/* ---- sdo_client_pool.c ------------------------------------------------------------ */

/* Start what can start: each idle channel's own FIFO, then the pool's
 * requests in order, then give the gate back what is no longer used. */
void sdo_cli_kick_all(struct sdo_client *cli);
/* Start the head of ch's own FIFO if ch is idle and its target free. */
void sdo_cli_kick(struct cli_chan *ch);
/* Give the gate back what the node's own requests no longer use. */
void sdo_cli_gate_sync(struct sdo_client *cli);
/* When the gate wants the tick again (CO_NO_DEADLINE: never). */
uint64_t sdo_cli_gate_next(const struct sdo_client *cli);
/* The i-th waiting request of the pool (0: the oldest); removing it. */
sdo_client_req *sdo_cli_pool_at(struct sdo_client *cli, uint16_t i);
void sdo_cli_pool_remove(struct sdo_client *cli, uint16_t i);
bool sdo_cli_req_valid(const sdo_client_req *r);

/* ---- sdo_client_xfer.c ------------------------------------------------------------ */

/* Set ch up for r and send its first frame; the state that waits for the
 * answer (or "start failed"). */
int sdo_cli_start_state(struct cli_chan *ch, const sdo_client_req *r);
/* The running request ends with `abort` (0 = success): the idle state,
 * whose on_enter confirms it. */
int sdo_cli_complete(struct cli_chan *ch, uint32_t abort);
/* The same after sending our abort frame with `code`. */
int sdo_cli_abort_local(struct cli_chan *ch, uint32_t code);
/* A server abort while a transfer runs: maybe fall back from block. */
int sdo_cli_server_abort(struct cli_chan *ch, int st, const uint8_t *d);
bool sdo_cli_is_abort(const uint8_t *d);
void sdo_cli_tx(struct cli_chan *ch, const uint8_t d[8]);
/* 1280h+n shows r's target on this bus (not a relayed request's). */
void sdo_cli_show_target(struct cli_chan *ch, const sdo_client_req *r);
/* A request's server COB-IDs (a relayed one's: an identity no COB-ID of
 * this bus has). */
uint32_t sdo_cli_cob_req(const sdo_client_req *r);
uint32_t sdo_cli_cob_resp(const sdo_client_req *r);

/* The transfer states of the machine (sdo_client.c's table): the per-frame
 * timer and its timeout, and each state's frame handler. */
int sdo_cli_transfer_on_enter(void *obj, uint64_t now_us);
int sdo_cli_transfer_on_timeout(void *obj, uint64_t now_us);
int sdo_cli_dn_init_on_frame(void *obj, const co_frame *f, uint64_t now_us);
int sdo_cli_dn_seg_on_frame(void *obj, const co_frame *f, uint64_t now_us);
int sdo_cli_up_init_on_frame(void *obj, const co_frame *f, uint64_t now_us);
int sdo_cli_up_seg_on_frame(void *obj, const co_frame *f, uint64_t now_us);
int sdo_cli_blk_dn_init_on_frame(void *obj, const co_frame *f, uint64_t now_us);
int sdo_cli_blk_dn_ack_on_frame(void *obj, const co_frame *f, uint64_t now_us);
int sdo_cli_blk_dn_end_on_frame(void *obj, const co_frame *f, uint64_t now_us);
int sdo_cli_blk_up_init_on_frame(void *obj, const co_frame *f, uint64_t now_us);
int sdo_cli_blk_up_sub_on_frame(void *obj, const co_frame *f, uint64_t now_us);
int sdo_cli_blk_up_end_on_frame(void *obj, const co_frame *f, uint64_t now_us);

#endif
