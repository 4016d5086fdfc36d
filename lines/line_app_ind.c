/* SPDX-License-Identifier: MIT */
/*
 * lines/line_app_ind.c - indications: an access to an object a client
 * owns, handed to the owner and answered when it answers
 * (docs/application.md). The whole transaction is here:
 *
 *   1. ind_open()       an SDO read or write of a served object (the OD
 *                       hooks below return CO_OD_DEFERRED: the SDO server
 *                       parks the channel, core/sdo_server.h), or a
 *                       mailbox OD_READ/OD_WRITE of one: a slot, a
 *                       deadline (the SDO server's timeout), the event
 *                       MBX_EV_APP_IND to the owner. No owner, too many
 *                       open, the owner's event queue full, or the
 *                       object's data in use by another transfer: the
 *                       access is refused at once (docs/sdo-answers.md).
 *   2. the owner        answers with APP_ANSWER (fetching a large write's
 *                       data with APP_IND_DATA first).
 *   3. ind_end()        exactly once: the owner's answer, the deadline
 *                       (line_app_poll, run before the core's own timers),
 *                       the owner gone or releasing the object, or the
 *                       requester gone (CO_EV_SDO_SERVER_DONE of its
 *                       channel: MBX_EV_APP_CANCEL to the owner).
 *
 * Held objects need no indication: their value is the daemon's; the owner
 * is told of every write by someone else (MBX_EV_APP_WRITTEN).
 *
 * Data: a served object's daemon copy (e->data) is scratch that no read
 * and no PDO ever uses, so it carries the value of one access at a time
 * (a mailbox write's data, a streamed SDO write, a read answer being
 * uploaded): `busy` guards it from the indication to the end of that
 * transfer.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <string.h>

#include "core/pdo.h"
#include "core/sdo.h"
#include "core/sdo_server.h"

/* ---- finding ------------------------------------------------------------- */

line_app_obj *line_app_find(line *l, const co_od_entry *e)
{
	line_app *a = l->app;
	for (uint16_t i = 0; a && i < a->n_obj; i++)
		if (a->obj[i].e == e)
			return &a->obj[i];
	return NULL;
}

line_app_obj *line_app_find_at(line *l, uint16_t index, uint8_t sub)
{
	line_app *a = l->app;
	for (uint16_t i = 0; a && i < a->n_obj; i++)
		if (a->obj[i].e->index == index && a->obj[i].e->sub == sub)
			return &a->obj[i];
	return NULL;
}

static line_app_ind *ind_by_id(line_app *a, uint32_t id)
{
	uint32_t slot = id & 0xFFu;
	if (!id || slot >= LINE_APP_IND_MAX || a->ind[slot].id != id)
		return NULL;
	return &a->ind[slot];
}

static unsigned open_of_owner(const line_app *a, uint32_t owner)
{
	unsigned n = 0;
	for (unsigned i = 0; i < LINE_APP_IND_MAX; i++)
		n += a->ind[i].id && a->ind[i].owner == owner;
	return n;
}

static mbx_reply_to owner_to(uint32_t owner, uint32_t corr)
{
	mbx_reply_to to = { .client = owner, .corr = corr };
	return to;
}

/* Does the access use the object's scratch copy? All but a mailbox read,
 * whose answer goes out from the owner's message at once. */
static bool uses_data(uint8_t op, uint8_t origin)
{
	return op == MBX_APP_OP_WRITE || origin == MBX_APP_FROM_SDO;
}

/* ---- opening --------------------------------------------------------------- */

typedef struct ind_req {
	uint8_t op, origin, channel;
	const uint8_t *data; /* write */
	uint32_t size;
	const mbx_reply_to *reply; /* mailbox origin */
} ind_req;

/* Why the access cannot wait for the owner (0: it can): the line answers. */
static uint32_t ind_refusal(line *l, const line_app_obj *o, const ind_req *r)
{
	line_app *a = l->app;
	if (!o->owner) {
		a->st.ind_no_owner++;
		return LINE_APP_AB_NO_OWNER;
	}
	bool same_transfer = r->origin == MBX_APP_FROM_SDO && o->busy_channel == r->channel;
	bool data_in_use = o->busy && !same_transfer && uses_data(r->op, r->origin);
	if (data_in_use || open_of_owner(a, o->owner) >= a->max_ind_per_client) {
		a->st.ind_refused_full++;
		return LINE_APP_AB_BUSY;
	}
	return 0;
}

static line_app_ind *ind_slot(line_app *a)
{
	for (unsigned i = 0; i < LINE_APP_IND_MAX; i++) {
		line_app_ind *in = &a->ind[i];
		if (!in->id) {
			in->gen = (uint8_t)(in->gen + 1) ? (uint8_t)(in->gen + 1) : 1;
			in->id = ((uint32_t)in->gen << 8) | i;
			return in;
		}
	}
	return NULL;
}

/* The event that hands the indication over: the write's first bytes, as
 * many as the owner's event messages hold. */
static int ind_send(line *l, const line_app_ind *in)
{
	uint8_t msg[MBX_MSG_MAX];
	size_t room = mbx_server_client_max_payload(l->mbx, in->owner);
	mbx_ev_app_ind ev = { .ind = in->id,
			      .index = in->obj->e->index,
			      .sub = in->obj->e->sub,
			      .op = in->op,
			      .origin = in->origin,
			      .channel = in->origin == MBX_APP_FROM_SDO ? in->channel : 0,
			      .size = in->op == MBX_APP_OP_WRITE ? in->size : 0,
			      .deadline_ms = l->app->timeout_ms,
			      .client = in->origin == MBX_APP_FROM_MAILBOX ? in->reply.client : 0 };
	if (room > sizeof msg)
		room = sizeof msg;
	if (room < sizeof ev)
		return -EMSGSIZE;
	uint32_t n = ev.size;
	if (n > room - sizeof ev)
		n = (uint32_t)(room - sizeof ev);
	ev.inline_len = (uint16_t)n;
	memcpy(msg, &ev, sizeof ev);
	if (n)
		memcpy(msg + sizeof ev, in->data, n);
	mbx_reply_to to = owner_to(in->owner, in->id);
	return mbx_server_notify(l->mbx, &to, MBX_EV_APP_IND, msg, sizeof ev + n);
}

/* Step 1: 0 with the indication sent to the owner, or the abort code the
 * line answers with at once. */
static uint32_t ind_open(line *l, line_app_obj *o, const ind_req *r)
{
	line_app *a = l->app;
	uint32_t ab = ind_refusal(l, o, r);
	if (ab)
		return ab;
	line_app_ind *in = ind_slot(a);
	if (!in) {
		a->st.ind_refused_full++;
		return LINE_APP_AB_BUSY;
	}
	in->op = r->op;
	in->origin = r->origin;
	in->channel = r->channel;
	in->obj = o;
	in->owner = o->owner;
	in->deadline_us = l->now_us + (uint64_t)a->timeout_ms * 1000u;
	in->data = r->data;
	in->size = r->size;
	if (r->reply)
		in->reply = *r->reply;
	if (ind_send(l, in) < 0) {
		in->id = 0;
		a->st.ind_refused_full++;
		return LINE_APP_AB_BUSY;
	}
	a->st.ind_sent++;
	o->open++;
	if (uses_data(r->op, r->origin)) {
		o->busy = true;
		o->busy_channel = r->origin == MBX_APP_FROM_SDO ? r->channel : LINE_APP_NO_CHANNEL;
	}
	return 0;
}

/* ---- ending ------------------------------------------------------------------ */

static void ind_free(line_app_ind *in)
{
	in->obj->open--;
	in->id = 0;
}

/* The data of the object is free again: a mailbox access ends with its
 * answer, an SDO one with its transfer (CO_EV_SDO_SERVER_DONE). */
static void obj_unbusy(line_app_obj *o)
{
	o->busy = false;
	o->busy_channel = LINE_APP_NO_CHANNEL;
}

/* Step 3 without the owner's value: the requester gets `abort`. */
static void ind_end_abort(line *l, line_app_ind *in, uint32_t abort)
{
	line_app_obj *o = in->obj;
	uint8_t origin = in->origin, channel = in->channel;
	bool held_data = uses_data(in->op, in->origin);
	mbx_reply_to reply = in->reply;
	/* freed first: the server reports the transfer's end from inside
	 * sdo_server_continue, and that report must find nothing open */
	ind_free(in);
	if (origin == MBX_APP_FROM_SDO) {
		/* the server's DONE event frees the data */
		sdo_server_continue(l->node, channel, abort, NULL, 0, l->now_us);
	} else {
		line_answer(l, &reply, MBX_E_ABORT, abort, NULL, 0);
		if (held_data)
			obj_unbusy(o);
	}
}

/* Tell the owner that an indication ended without its answer. */
static void ind_cancel_notice(line *l, const line_app_ind *in, uint32_t abort)
{
	mbx_ev_app_cancel c = { .ind = in->id, .abort = abort };
	mbx_reply_to to = owner_to(in->owner, in->id);
	mbx_server_notify(l->mbx, &to, MBX_EV_APP_CANCEL, &c, sizeof c);
}

void line_app_ind_end_all(line *l, const line_app_obj *obj, uint32_t owner, uint32_t abort)
{
	line_app *a = l->app;
	for (unsigned i = 0; a && i < LINE_APP_IND_MAX; i++) {
		line_app_ind *in = &a->ind[i];
		if (!in->id || (obj && in->obj != obj) || (owner && in->owner != owner))
			continue;
		a->st.ind_no_owner++;
		ind_cancel_notice(l, in, abort);
		ind_end_abort(l, in, abort);
	}
}

uint64_t line_app_poll(line *l, uint64_t now_us)
{
	line_app *a = l->app;
	uint64_t next = UINT64_MAX;
	for (unsigned i = 0; a && i < LINE_APP_IND_MAX; i++) {
		line_app_ind *in = &a->ind[i];
		if (!in->id)
			continue;
		if (in->deadline_us <= now_us) {
			a->st.ind_late++;
			ind_cancel_notice(l, in, LINE_APP_AB_LATE);
			ind_end_abort(l, in, LINE_APP_AB_LATE);
		} else if (in->deadline_us < next) {
			next = in->deadline_us;
		}
	}
	return next;
}

/* ---- the OD hooks of owned objects (SDO from the bus) -------------------- */

static uint32_t hook_read(void *ctx, co_od_entry *e, const co_od_access *acc)
{
	line_app_obj *o = ctx;
	(void)e;
	if (o->kind != MBX_APP_SERVED || acc->origin != CO_OD_ORIGIN_SDO)
		return 0; /* a held value is the daemon's: read it now */
	ind_req r = { .op = MBX_APP_OP_READ, .origin = MBX_APP_FROM_SDO, .channel = acc->channel };
	uint32_t ab = ind_open(o->l, o, &r);
	return ab ? ab : CO_OD_DEFERRED;
}

/* A staged SDO write (all data known), or the initiate of one streamed
 * in place (data NULL: only whether someone can answer at its end). */
static uint32_t hook_check_write(void *ctx, co_od_entry *e, const co_od_access *acc)
{
	line_app_obj *o = ctx;
	(void)e;
	if (o->kind != MBX_APP_SERVED || acc->origin != CO_OD_ORIGIN_SDO)
		return 0;
	ind_req r = { .op = MBX_APP_OP_WRITE,
		      .origin = MBX_APP_FROM_SDO,
		      .channel = acc->channel,
		      .data = acc->data,
		      .size = acc->size };
	if (!acc->data) {
		uint32_t ab = ind_refusal(o->l, o, &r);
		if (!ab) { /* the bytes will stream into e->data */
			o->busy = true;
			o->busy_channel = acc->channel;
		}
		return ab;
	}
	uint32_t ab = ind_open(o->l, o, &r);
	return ab ? ab : CO_OD_DEFERRED;
}

static uint32_t hook_check_streamed(void *ctx, co_od_entry *e, const co_od_access *acc)
{
	return hook_check_write(ctx, e, acc);
}

/* Someone else wrote a held object: its owner hears of it. */
static void written_notice(line *l, line_app_obj *o, uint8_t origin, uint16_t pdo, uint32_t client)
{
	line_app *a = l->app;
	if (!o->owner || o->kind != MBX_APP_HELD || client == o->owner)
		return;
	uint8_t msg[MBX_MSG_MAX];
	size_t room = mbx_server_client_max_payload(l->mbx, o->owner);
	mbx_ev_app_written w = { .index = o->e->index,
				 .sub = o->e->sub,
				 .origin = origin,
				 .pdo = pdo,
				 .size = o->e->size,
				 .client = client };
	if (room > sizeof msg)
		room = sizeof msg;
	if (room < sizeof w)
		return;
	uint32_t n = w.size;
	if (n > room - sizeof w)
		n = (uint32_t)(room - sizeof w);
	w.inline_len = (uint16_t)n;
	memcpy(msg, &w, sizeof w);
	memcpy(msg + sizeof w, o->e->data, n);
	mbx_reply_to to = owner_to(o->owner, 0);
	if (mbx_server_notify(l->mbx, &to, MBX_EV_APP_WRITTEN, msg, sizeof w + n) == 0)
		a->st.written_events++;
}

static void hook_after_write(void *ctx, co_od_entry *e, const co_od_access *acc)
{
	line_app_obj *o = ctx;
	(void)e;
	/* mailbox writes are told by line_app_od_write, which knows the
	 * writer; RPDO values by CO_EV_RPDO_OBJECT, which knows the PDO */
	if (acc->origin == CO_OD_ORIGIN_SDO)
		written_notice(o->l, o, MBX_APP_FROM_SDO, 0, 0);
}

const co_od_hooks line_app_hooks = {
	.read = hook_read,
	.check_write = hook_check_write,
	.check_streamed = hook_check_streamed,
	.after_write = hook_after_write,
};

/* ---- the mailbox's accesses to owned objects ---------------------------- */

void line_app_od_read(line *l, const mbx_request *req, line_app_obj *o)
{
	co_od_entry *e = o->e;
	if (o->kind == MBX_APP_HELD)
		return line_answer(l, &req->reply, 0, 0, e->data, e->size);
	/* the owner keeps a served value: it would wait for itself */
	if (req->reply.client == o->owner)
		return line_answer(l, &req->reply, MBX_E_STATE, 0, NULL, 0);
	ind_req r = { .op = MBX_APP_OP_READ, .origin = MBX_APP_FROM_MAILBOX, .reply = &req->reply };
	uint32_t ab = ind_open(l, o, &r);
	if (ab)
		line_answer(l, &req->reply, MBX_E_ABORT, ab, NULL, 0);
}

static void held_write(line *l, const mbx_request *req, line_app_obj *o, bool trigger_pdo)
{
	co_od_entry *e = o->e;
	co_od_access acc = { .origin = CO_OD_ORIGIN_LOCAL,
			     .data = req->data,
			     .size = (uint32_t)req->data_len };
	uint32_t ab = co_od_write(e, req->data, (uint32_t)req->data_len, &acc);
	if (ab)
		return line_answer(l, &req->reply, MBX_E_ABORT, ab, NULL, 0);
	if (trigger_pdo)
		co_pdo_object_changed(l->node, e->index, e->sub, l->now_us);
	written_notice(l, o, MBX_APP_FROM_MAILBOX, 0, req->reply.client);
	line_answer(l, &req->reply, 0, 0, NULL, 0);
}

void line_app_od_write(line *l, const mbx_request *req, line_app_obj *o, bool trigger_pdo)
{
	co_od_entry *e = o->e;
	if (o->kind == MBX_APP_HELD)
		return held_write(l, req, o, trigger_pdo);
	if (req->reply.client == o->owner)
		return line_answer(l, &req->reply, MBX_E_STATE, 0, NULL, 0);
	uint32_t len = (uint32_t)req->data_len;
	uint32_t ab = co_od_check_value(e, req->data, len);
	ind_req r = { .op = MBX_APP_OP_WRITE,
		      .origin = MBX_APP_FROM_MAILBOX,
		      .data = e->data,
		      .size = len,
		      .reply = &req->reply };
	if (!ab)
		ab = ind_refusal(l, o, &r);
	if (ab)
		return line_answer(l, &req->reply, MBX_E_ABORT, ab, NULL, 0);
	/* the request's data lives only as long as this call: the served
	 * object's scratch copy keeps it (guarded by busy from here on) */
	co_od_entry_set_bytes(e, req->data, len);
	ab = ind_open(l, o, &r);
	if (ab)
		line_answer(l, &req->reply, MBX_E_ABORT, ab, NULL, 0);
}

/* ---- the owner's answer ----------------------------------------------------- */

/* A read answer that fits the object: 0, else the abort the requester
 * gets instead. */
static uint32_t read_value_check(const co_od_entry *e, const mbx_request *req)
{
	if (co_type_is_variable((co_type)e->type))
		return req->data_len <= e->max_size ? 0 : LINE_APP_AB_BAD_ANSWER;
	return req->data_len == e->size ? 0 : LINE_APP_AB_BAD_ANSWER;
}

static void answer_read(line *l, line_app_ind *in, const mbx_request *req)
{
	co_od_entry *e = in->obj->e;
	if (in->origin == MBX_APP_FROM_MAILBOX) {
		line_answer(l, &in->reply, 0, 0, req->data, req->data_len);
		return ind_free(in);
	}
	/* uploaded from the scratch copy, which stays busy until the
	 * transfer's end */
	co_od_entry_set_bytes(e, req->data, (uint32_t)req->data_len);
	uint8_t channel = in->channel;
	ind_free(in);
	sdo_server_continue(l->node, channel, 0, NULL, 0, l->now_us);
}

static void answer_write(line *l, line_app_ind *in)
{
	co_od_entry *e = in->obj->e;
	if (in->origin == MBX_APP_FROM_SDO) {
		uint8_t channel = in->channel;
		ind_free(in);
		sdo_server_continue(l->node, channel, 0, NULL, 0, l->now_us);
		return;
	}
	co_od_access acc = { .origin = CO_OD_ORIGIN_LOCAL, .data = e->data, .size = in->size };
	co_od_commit(e, e->data, in->size, &acc);
	line_answer(l, &in->reply, 0, 0, NULL, 0);
	obj_unbusy(in->obj);
	ind_free(in);
}

/* The indication the owner may answer, or NULL (counted). */
static line_app_ind *owners_ind(line *l, const mbx_request *req, uint32_t id)
{
	line_app_ind *in = ind_by_id(l->app, id);
	if (in && in->owner == req->reply.client)
		return in;
	l->app->st.answers_refused++;
	return NULL;
}

void line_app_answer(line *l, const mbx_request *req)
{
	mbx_app_answer_req r;
	memcpy(&r, req->payload, sizeof r);
	line_app_ind *in = l->app ? owners_ind(l, req, r.ind) : NULL;
	if (!in)
		return line_answer(l, &req->reply, MBX_E_PARAM, 0, NULL, 0);
	if ((r.abort || in->op == MBX_APP_OP_WRITE) && req->data_len) {
		l->app->st.answers_refused++;
		return line_answer(l, &req->reply, MBX_E_PARAM, 0, NULL, 0);
	}
	uint32_t ab = r.abort;
	if (!ab && in->op == MBX_APP_OP_READ)
		ab = read_value_check(in->obj->e, req);
	l->app->st.ind_answered++;
	/* the owner learns that its value did not fit; the requester gets
	 * an answer all the same */
	int status = ab && !r.abort ? MBX_E_PARAM : 0;
	if (ab)
		ind_end_abort(l, in, ab);
	else if (in->op == MBX_APP_OP_READ)
		answer_read(l, in, req);
	else
		answer_write(l, in);
	line_answer(l, &req->reply, status, 0, NULL, 0);
}

void line_app_ind_data(line *l, const mbx_request *req)
{
	mbx_app_ind_req r;
	memcpy(&r, req->payload, sizeof r);
	line_app_ind *in = l->app ? owners_ind(l, req, r.ind) : NULL;
	if (!in || in->op != MBX_APP_OP_WRITE)
		return line_answer(l, &req->reply, MBX_E_PARAM, 0, NULL, 0);
	line_answer(l, &req->reply, 0, 0, in->data, in->size);
}

/* ---- core events --------------------------------------------------------------- */

/* A server transfer ended: an indication still open for it lost its
 * requester (client abort, timeout, NMT stopped); the data is free. */
static void server_done(line *l, const co_ev_sdo_srv *d)
{
	line_app *a = l->app;
	for (unsigned i = 0; i < LINE_APP_IND_MAX; i++) {
		line_app_ind *in = &a->ind[i];
		if (in->id && in->origin == MBX_APP_FROM_SDO && in->channel == d->channel) {
			a->st.ind_cancelled++;
			ind_cancel_notice(l, in, d->abort);
			ind_free(in);
		}
	}
	for (uint16_t i = 0; i < a->n_obj; i++)
		if (a->obj[i].busy && a->obj[i].busy_channel == d->channel)
			obj_unbusy(&a->obj[i]);
}

void line_app_on_core_event(line *l, const co_event *ev)
{
	if (!l->app)
		return;
	if (ev->kind == CO_EV_SDO_SERVER_DONE) {
		server_done(l, &ev->u.sdo_srv);
	} else if (ev->kind == CO_EV_RPDO_OBJECT && !ev->u.pdo_obj.abort) {
		line_app_obj *o = line_app_find_at(l, ev->u.pdo_obj.index, ev->u.pdo_obj.sub);
		if (o)
			written_notice(l, o, MBX_APP_FROM_RPDO, ev->u.pdo_obj.nr, 0);
	}
}
