/* SPDX-License-Identifier: MIT */
/*
 * lines/line_app.h - objects a client owns on the line's own node
 * (docs/application.md), shared by the two files that run them:
 *
 *   line_app.c      the objects: declared ones at start-up, APP_CLAIM
 *                   (claim or create), APP_RELEASE, APP_LIST, a client
 *                   that leaves
 *   line_app_ind.c  the indications: the OD hooks of owned objects (SDO
 *                   reads and writes from the bus, deferred), the mailbox's
 *                   OD_READ/OD_WRITE of them, APP_ANSWER, APP_IND_DATA,
 *                   deadlines, the end of a server transfer, RPDO values
 *
 * line_app.c calls line_app_ind.c, never the other way round.
 *
 * One indication = one access waiting for its owner: a slot of a fixed
 * table (LINE_APP_IND_MAX per line, at most max_ind_per_client per owner),
 * named to the owner by an id (slot number and a generation, so an answer
 * to a slot that was reused is refused). It ends exactly once: the owner
 * answers, the deadline (the SDO server's timeout) passes, the owner goes,
 * or the requester goes (SDO abort or timeout).
 *
 * The line thread only; nothing here waits for a client.
 */
#ifndef COGW_LINES_LINE_APP_H
#define COGW_LINES_LINE_APP_H

#include <stdbool.h>
#include <stdint.h>

#include "core/event.h"
#include "core/od.h"
#include "mailbox/server.h"

typedef struct line line;

#define LINE_APP_IND_MAX 32u
#define LINE_APP_NO_CHANNEL 0xFFu

/* CiA 301 abort codes the line answers by itself (docs/sdo-answers.md). */
#define LINE_APP_AB_LATE 0x08000020u     /* the owner did not answer in time */
#define LINE_APP_AB_NO_OWNER 0x08000021u /* nobody owns it (gone, released) */
#define LINE_APP_AB_BUSY \
	0x060A0023u                        /* too many open / the owner's queue full /
					  * another transfer of its data under way */
#define LINE_APP_AB_BAD_ANSWER 0x06040047u /* the owner's value does not fit the object */

typedef struct line_app_obj {
	line *l;
	co_od_entry *e;
	uint8_t kind; /* mbx_app_kind */
	bool declared;
	uint8_t busy_channel; /* SDO channel whose transfer uses e->data, or
	                       * LINE_APP_NO_CHANNEL */
	bool busy;            /* e->data belongs to one access until it ends */
	uint32_t uid;         /* who may claim it */
	uint32_t owner;       /* client id, 0 = none */
	uint16_t open;        /* indications open on it */
	uint16_t pad;
} line_app_obj;

typedef struct line_app_ind {
	uint32_t id;     /* 0 = free slot */
	uint8_t op;      /* mbx_app_op */
	uint8_t origin;  /* mbx_app_origin */
	uint8_t channel; /* SDO origin */
	uint8_t gen;
	line_app_obj *obj;
	uint32_t owner;
	uint64_t deadline_us;
	mbx_reply_to reply;  /* mailbox origin: the requester */
	const uint8_t *data; /* write: the new value (SDO stage or e->data) */
	uint32_t size;
} line_app_ind;

typedef struct line_app {
	line_app_obj *obj; /* n_obj used of cap */
	uint16_t n_obj, cap;
	uint16_t n_created;
	uint16_t max_created, max_per_client, max_ind_per_client;
	uint32_t timeout_ms; /* the SDO server's per-frame timeout */
	line_app_ind ind[LINE_APP_IND_MAX];
	mbx_app_status st; /* counters (n and the bounds filled by APP_LIST) */
	uint8_t *list;     /* APP_LIST's answer: the status and cap objects */
} line_app;

/* line_app.c */
int line_app_attach(line *l); /* after the node exists: the declared objects */
void line_app_detach(line *l);
void line_app_claim(line *l, const mbx_request *req);
void line_app_release(line *l, const mbx_request *req);
void line_app_list(line *l, const mbx_request *req);
void line_app_client_gone(line *l, uint32_t client);

/* line_app_ind.c */
/* The owned object of this entry / of index:sub, or NULL. */
line_app_obj *line_app_find(line *l, const co_od_entry *e);
line_app_obj *line_app_find_at(line *l, uint16_t index, uint8_t sub);
extern const co_od_hooks line_app_hooks; /* ctx: the line_app_obj */
/* OD_READ / OD_WRITE / PDO_WRITE / SDO to the own node of an owned object
 * (its access rights already checked): answered now or by the owner. */
void line_app_od_read(line *l, const mbx_request *req, line_app_obj *o);
void line_app_od_write(line *l, const mbx_request *req, line_app_obj *o, bool trigger_pdo);
void line_app_answer(line *l, const mbx_request *req);
void line_app_ind_data(line *l, const mbx_request *req);
/* End the open indications of obj (NULL: all) owned by `owner` (0: any
 * owner) with `abort`. */
void line_app_ind_end_all(line *l, const line_app_obj *obj, uint32_t owner, uint32_t abort);
/* A server transfer ended, an RPDO wrote an object. */
void line_app_on_core_event(line *l, const co_event *ev);
/* Deadlines due at now_us; the next one (UINT64_MAX: none). */
uint64_t line_app_poll(line *l, uint64_t now_us);

#endif /* COGW_LINES_LINE_APP_H */
