/* SPDX-License-Identifier: MIT */
/*
 * devobj/devobj_int.h - what the files of the device object extension
 * share (one line's state). Files:
 *   devobj.c        the extension ops and the mirror's life cycle
 *   object.c        where a device object is; the commands' answers
 *   mirror.c        programming the daemon's PDOs (core only)
 *   value.c         a value in a PDO frame by its type (core only)
 *   watch.c         DEV_WATCH/UNWATCH, the watch table, MBX_EV_DEV_VALUE
 *   read_write.c    DEV_READ, DEV_WRITE (mirror or PDO, else SDO)
 *   layout_answer.c DEV_LAYOUT
 * Line thread only; everything allocated at attach.
 */
#ifndef COGW_DEVOBJ_DEVOBJ_INT_H
#define COGW_DEVOBJ_DEVOBJ_INT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "devobj/devobj.h"
#include "devobj/mirror.h"

#define DEVOBJ_NO_WATCH (-1)
/* Bytes of a value DEV_READ answers (longer: TOO_BIG; SDO_UPLOAD reads it). */
#define DEVOBJ_READ_MAX 1024u
/* DEV_READ/WRITE by SDO under way (the line's pending table bounds them
 * anyway). */
#define DEVOBJ_SDO_CALLS 64u

/* The last frame of a device TPDO the mirror consumes (one per daemon
 * RPDO record): the values of every object it maps. */
typedef struct devobj_rx {
	uint8_t frame[8];
	uint8_t len;
	uint8_t node;        /* whose PDO the record mirrors (0 = none) */
	int16_t first_watch; /* watches of this record's objects */
	uint32_t generation; /* of that node's layout */
	uint32_t count;      /* frames received since mirrored */
	uint64_t time_us;    /* reception of the last one */
} devobj_rx;

/* The frame the mirror produces for a device RPDO (one per daemon TPDO
 * record): the values clients wrote, sent when every object has one. */
typedef struct devobj_tx {
	uint8_t frame[8];
	uint8_t node;
	bool dirty; /* a value changed since the frame was sent */
	uint32_t generation;
	uint64_t given;   /* bit n: entry n has been given a value */
	uint64_t due_us;  /* dirty: when to send (update time) */
	uint64_t sent_us; /* last sent */
	uint32_t sent;    /* frames sent */
	uint32_t resets;  /* the mirror's resets it has seen (mirror.h) */
} devobj_tx;

typedef struct devobj_watch {
	bool used;
	bool pending; /* a value arrived inside the interval */
	uint8_t node;
	uint8_t sub;
	uint16_t index;
	uint16_t type; /* co_type asked for (0 = the known one) */
	int16_t rec;   /* daemon RPDO record carrying it, -1 = not mirrored now */
	int16_t next;  /* next watch of the same record */
	uint8_t pos;   /* entry in the device TPDO */
	uint32_t interval_ms;
	uint32_t seq; /* events sent */
	uint64_t sent_us;
	mbx_reply_to reply; /* the client and the correlation of its WATCH */
} devobj_watch;

/* A DEV_READ/WRITE that went to SDO, until its confirmation. */
typedef struct devobj_sdo_call {
	bool used;
	struct devobj_line *dl;
	uint8_t node;
	uint8_t sub;
	uint16_t index;
	uint16_t type; /* the value's co_type, 0 = from the answer's length */
} devobj_sdo_call;

/* Counters of one end of a forwarded device object (devobj/forward.c). */
typedef struct devobj_fwd_counters {
	uint32_t values;     /* source: into the image; target: taken from it */
	uint32_t superseded; /* target: replaced before a frame carried it */
	uint32_t refused;    /* not mirrored, or a value the bits cannot hold */
} devobj_fwd_counters;

typedef struct devobj_line {
	devobj_line_params p;
	line *l;
	devobj_mirror mirror;
	uint8_t mirrored[CO_PDO_LAYOUT_NODES]; /* the nodes with pdo "auto" */
	unsigned n_mirrored;
	devobj_rx *rx; /* [daemon RPDO record] */
	devobj_tx *tx; /* [daemon TPDO record] */
	devobj_watch *watch;
	uint16_t n_watch_used;
	unsigned n_pending; /* watches whose latest value waits for the interval */
	unsigned n_dirty;   /* TX records with a frame due */
	devobj_sdo_call *calls;
	uint8_t read_buf[sizeof(mbx_dev_value) + DEVOBJ_READ_MAX]; /* DEV_READ by SDO */
	uint8_t *layout_buf;                                       /* DEV_LAYOUT answer */
	size_t layout_buf_cap;
	devobj_fwd_counters fwd[DEVOBJ_FORWARDS_MAX];
	/* counters */
	uint32_t watch_refused; /* table full */
	uint32_t tx_failed;     /* a produced PDO the core refused */
} devobj_line;

/* Where a device object is mapped: the device PDO of direction dev_dir
 * mapping it and the entry, the record mirroring that PDO (-1 = none). */
typedef struct devobj_place {
	const co_pdo_layout_pdo *pdo;
	const co_pdo_layout_entry *entry;
	uint8_t pos;
	int rec;
} devobj_place;

/* watch.c */
int devobj_watch_init(devobj_line *dl);
void devobj_watch_fini(devobj_line *dl);
void devobj_watch_relink(devobj_line *dl);
void devobj_watch_received(devobj_line *dl, unsigned rec, uint64_t now_us);
void devobj_watch_client_gone(devobj_line *dl, uint32_t client);
uint64_t devobj_watch_poll(devobj_line *dl, uint64_t now_us);
void devobj_cmd_watch(devobj_line *dl, const mbx_request *req);
void devobj_cmd_unwatch(devobj_line *dl, const mbx_request *req);

/* read_write.c */
void devobj_cmd_read(devobj_line *dl, const mbx_request *req);
void devobj_cmd_write(devobj_line *dl, const mbx_request *req);
uint64_t devobj_write_poll(devobj_line *dl, uint64_t now_us);
/* Entry at->pos of the frame of record at->rec has its value now: the
 * frame goes when every object of the device's RPDO has one - within the
 * update time, or in this loop when at_once. Returns whether it is held. */
bool devobj_tx_given(devobj_line *dl, const devobj_place *at, bool at_once);
/* Record i's frame goes now: the slot takes it and the TPDO is triggered
 * (its gate may say another line's thread sent it already,
 * docs/gateway.md "One wake-up per hop"). */
void devobj_tx_send(devobj_line *dl, unsigned i, uint64_t now_us);

/* forward.c */
void devobj_forward_received(devobj_line *dl, unsigned rec, uint64_t now_us);
void devobj_forward_updated(devobj_line *dl, uint16_t index, uint8_t sub);
/* The objects of the frames the forwards fill alone (line_tpdo_sources):
 * after the mirror changed. */
void devobj_forward_sources(devobj_line *dl);
void devobj_cmd_forwards(devobj_line *dl, const mbx_request *req);

/* layout_answer.c */
size_t devobj_layout_answer_max(const devobj_line *dl);
void devobj_cmd_layout(devobj_line *dl, const mbx_request *req);

/* false: node has no valid layout or does not map index:sub that way. */
bool devobj_find(const devobj_line *dl, uint8_t node, co_pdo_dir dev_dir, uint16_t index,
		 uint8_t sub, devobj_place *out);

/* Answer a request. */
void devobj_answer(devobj_line *dl, const mbx_reply_to *to, int status, uint32_t abort,
		   const void *payload, size_t len);

#endif /* COGW_DEVOBJ_DEVOBJ_INT_H */
