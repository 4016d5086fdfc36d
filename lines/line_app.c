/* SPDX-License-Identifier: MIT */
/*
 * lines/line_app.c - objects a client owns on the line's own node
 * (docs/application.md): the table of them, APP_CLAIM, APP_RELEASE,
 * APP_LIST and a client that leaves. Their accesses are
 * lines/line_app_ind.c's.
 *
 * Who may own what (the rights of writes, docs/mailbox.md "Security
 * model"): APP_* commands that change anything are write-type, so a
 * read-only client never reaches this file with them; a declared object
 * is claimed only by a client of the user the configuration names (or
 * root); a created one only in 2000h..5FFFh / 6000h..9FFFh (checked by the
 * mailbox, mailbox/proto.c), never on an index the daemon already has
 * for itself, and re-claimed after its owner left only by the same user.
 * Bounds: max_created objects created per line, max_per_client owned by
 * one client. Created objects stay in the OD until the daemon stops (a
 * PDO may map them; the OD has no removal): released, they answer as an
 * object without owner.
 *
 * Creating an object allocates its entry (co_od_add), once, on a mailbox
 * command within those bounds; nothing on a frame's path allocates.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "lines/log.h"

#define APP_DEFAULT_CREATED 100u
#define APP_DEFAULT_PER_CLIENT 64u
#define APP_DEFAULT_IND_PER_CLIENT 8u
#define APP_DEFAULT_SDO_TIMEOUT_MS 1000u /* core/co.h sdo_server_timeout_ms */

static uint16_t or_default(uint16_t v, uint16_t def)
{
	return v ? v : def;
}

static line_app_obj *obj_add(line *l, co_od_entry *e, uint8_t kind, uint32_t uid, bool declared)
{
	line_app *a = l->app;
	if (a->n_obj >= a->cap)
		return NULL;
	line_app_obj *o = &a->obj[a->n_obj++];
	*o = (line_app_obj){ .l = l,
			     .e = e,
			     .kind = kind,
			     .declared = declared,
			     .busy_channel = LINE_APP_NO_CHANNEL,
			     .uid = uid };
	co_od_entry_set_hooks(e, &line_app_hooks, o);
	return o;
}

int line_app_attach(line *l)
{
	const line_app_params *p = &l->p.app;
	line_app *a = calloc(1, sizeof *a);
	if (!a)
		return -ENOMEM;
	a->max_created = or_default(p->max_created, APP_DEFAULT_CREATED);
	a->max_per_client = or_default(p->max_per_client, APP_DEFAULT_PER_CLIENT);
	a->max_ind_per_client = or_default(p->max_ind_per_client, APP_DEFAULT_IND_PER_CLIENT);
	a->timeout_ms = l->p.node.sdo_server_timeout_ms ? l->p.node.sdo_server_timeout_ms
							: APP_DEFAULT_SDO_TIMEOUT_MS;
	a->cap = (uint16_t)(p->n_decl + a->max_created);
	a->obj = calloc(a->cap ? a->cap : 1, sizeof *a->obj);
	a->list = malloc(sizeof(mbx_app_status) + (size_t)a->cap * sizeof(mbx_app_obj));
	l->app = a;
	if (!a->obj || !a->list)
		return -ENOMEM;
	for (uint16_t i = 0; i < p->n_decl; i++) {
		const line_app_decl *d = &p->decl[i];
		co_od_entry *e = co_od_find(co_node_od(l->node), d->index, d->sub);
		if (!e || d->index < 0x2000 || d->index > 0x9FFF) {
			cogw_log(COGW_LOG_ERR, "line %s: application object %04Xh:%u: %s", l->name,
				 d->index, d->sub, e ? "outside 2000h..9FFFh" : "not defined");
			return -EINVAL;
		}
		obj_add(l, e, d->kind, d->uid, true);
	}
	l->p.app.decl = NULL; /* the caller's, valid only during line_create */
	return 0;
}

void line_app_detach(line *l)
{
	if (!l->app)
		return;
	for (uint16_t i = 0; i < l->app->n_obj; i++)
		co_od_entry_set_hooks(l->app->obj[i].e, NULL, NULL);
	free(l->app->obj);
	free(l->app->list);
	free(l->app);
	l->app = NULL;
}

static unsigned owned_by(const line_app *a, uint32_t client)
{
	unsigned n = 0;
	for (uint16_t i = 0; i < a->n_obj; i++)
		n += a->obj[i].owner == client;
	return n;
}

static uint8_t wire_access(uint16_t acc)
{
	return (uint8_t)(acc & (CO_ACC_READ | CO_ACC_WRITE | CO_ACC_RPDO | CO_ACC_TPDO));
}

/* An object that exists: may this client have it? 0 or a refusal status. */
static int claim_existing(line *l, const mbx_request *req, const mbx_app_claim_req *r,
			  line_app_obj *o)
{
	line_app *a = l->app;
	if (o->owner == req->reply.client)
		return 0; /* again: nothing changes */
	if (o->owner || (req->uid != o->uid && req->uid != 0))
		return MBX_E_ACCESS;
	if (r->kind != o->kind ||
	    (r->type && (r->type != o->e->type || r->access != wire_access(o->e->access))))
		return MBX_E_PARAM;
	if (owned_by(a, req->reply.client) >= a->max_per_client)
		return MBX_E_FULL;
	o->owner = req->reply.client;
	return 0;
}

/* A new object (its index checked by the mailbox). 0 or a status. */
static int claim_new(line *l, const mbx_request *req, const mbx_app_claim_req *r)
{
	line_app *a = l->app;
	co_od *od = co_node_od(l->node);
	if (!r->type)
		return MBX_E_PARAM; /* nothing declared there */
	/* the index may only grow by sub-indexes of this client's own objects */
	if (co_od_has_index(od, r->index)) {
		bool own = false;
		for (uint16_t i = 0; i < a->n_obj; i++)
			own |= a->obj[i].e->index == r->index &&
			       a->obj[i].owner == req->reply.client;
		if (!own)
			return MBX_E_ACCESS;
	}
	if (a->n_created >= a->max_created || owned_by(a, req->reply.client) >= a->max_per_client)
		return MBX_E_FULL;
	uint16_t acc = r->access & (MBX_APP_READ | MBX_APP_WRITE | MBX_APP_RPDO | MBX_APP_TPDO);
	co_od_desc d = { .index = r->index,
			 .sub = r->sub,
			 .type = (uint8_t)r->type,
			 .access = acc,
			 .max_size = r->max_size,
			 .def = req->data_len ? req->data : NULL,
			 .def_size = (uint32_t)req->data_len };
	if (co_type_is_variable((co_type)r->type) && !r->max_size)
		return MBX_E_PARAM;
	co_od_entry *e = NULL;
	int rc = co_od_add(od, &d, &e);
	if (rc < 0)
		return rc == -EINVAL ? MBX_E_PARAM : mbx_status_of_errno(rc);
	line_app_obj *o = obj_add(l, e, r->kind, req->uid, false);
	o->owner = req->reply.client;
	a->n_created++;
	return 0;
}

void line_app_claim(line *l, const mbx_request *req)
{
	mbx_app_claim_req r;
	memcpy(&r, req->payload, sizeof r);
	if (!l->app)
		return line_answer(l, &req->reply, MBX_E_UNSUPPORTED, 0, NULL, 0);
	line_app_obj *o = line_app_find_at(l, r.index, r.sub);
	int status;
	if (o)
		status = claim_existing(l, req, &r, o);
	else if (co_od_find(co_node_od(l->node), r.index, r.sub))
		status = MBX_E_ACCESS; /* the daemon's own object */
	else
		status = claim_new(l, req, &r);
	if (status)
		l->app->st.claims_refused++;
	else
		cogw_log(COGW_LOG_INFO, "line %s: client %u owns %04Xh:%u (%s)", l->name,
			 req->reply.client, r.index, r.sub,
			 r.kind == MBX_APP_SERVED ? "served" : "held");
	line_answer(l, &req->reply, status, 0, NULL, 0);
}

void line_app_release(line *l, const mbx_request *req)
{
	mbx_obj_req r;
	memcpy(&r, req->payload, sizeof r);
	line_app_obj *o = l->app ? line_app_find_at(l, r.index, r.sub) : NULL;
	if (!o || o->owner != req->reply.client)
		return line_answer(l, &req->reply, MBX_E_PARAM, 0, NULL, 0);
	o->owner = 0;
	line_app_ind_end_all(l, o, 0, LINE_APP_AB_NO_OWNER);
	line_answer(l, &req->reply, 0, 0, NULL, 0);
}

void line_app_list(line *l, const mbx_request *req)
{
	line_app *a = l->app;
	if (!a)
		return line_answer(l, &req->reply, MBX_E_UNSUPPORTED, 0, NULL, 0);
	size_t len = sizeof(mbx_app_status) + (size_t)a->n_obj * sizeof(mbx_app_obj);
	uint8_t *buf = a->list;
	mbx_app_status st = a->st;
	st.n = a->n_obj;
	st.max_objects = a->cap;
	st.max_per_client = a->max_per_client;
	st.max_ind_per_client = a->max_ind_per_client;
	memcpy(buf, &st, sizeof st);
	for (uint16_t i = 0; i < a->n_obj; i++) {
		const line_app_obj *o = &a->obj[i];
		mbx_app_obj w = { .index = o->e->index,
				  .sub = o->e->sub,
				  .kind = o->kind,
				  .type = o->e->type,
				  .access = wire_access(o->e->access),
				  .declared = o->declared,
				  .owner = o->owner,
				  .uid = o->uid,
				  .max_size = o->e->max_size,
				  .open = o->open };
		memcpy(buf + sizeof st + i * sizeof w, &w, sizeof w);
	}
	line_answer(l, &req->reply, 0, 0, buf, len);
}

void line_app_client_gone(line *l, uint32_t client)
{
	line_app *a = l->app;
	if (!a)
		return;
	bool had = false;
	for (uint16_t i = 0; i < a->n_obj; i++)
		if (a->obj[i].owner == client) {
			a->obj[i].owner = 0;
			had = true;
		}
	line_app_ind_end_all(l, NULL, client, LINE_APP_AB_NO_OWNER);
	if (had)
		cogw_log(COGW_LOG_INFO, "line %s: client %u left: its objects have no owner",
			 l->name, client);
}
