/* SPDX-License-Identifier: MIT */
/*
 * lines/line_od.c - mailbox commands on the line's own object dictionary:
 * OD_READ / OD_WRITE, and their PDO variants (PDO_READ, PDO_WRITE with an
 * optional TPDO trigger, PDO_REQUEST). Answered at once; what is checked
 * here is what only the line knows (does the object exist, may it be read
 * or written). An object a client owns goes to lines/line_app_ind.c,
 * which may answer later (docs/application.md).
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <string.h>

#include "core/pdo.h"
#include "core/sdo.h"

static void od_read_at(line *l, const mbx_request *req, uint16_t index, uint8_t sub)
{
	uint32_t abort = 0;
	co_od_entry *e = co_od_find_ex(co_node_od(l->node), index, sub, &abort);
	if (!e)
		return line_answer(l, &req->reply, MBX_E_ABORT, abort, NULL, 0);
	if (!(e->access & CO_ACC_READ))
		return line_answer(l, &req->reply, MBX_E_ABORT, SDO_AB_WRITE_ONLY, NULL, 0);
	line_app_obj *o = line_app_find(l, e);
	if (o) /* a client owns it: its value may be the client's to give */
		return line_app_od_read(l, req, o);
	line_answer(l, &req->reply, 0, 0, e->data, e->size);
}

void line_od_read(line *l, const mbx_request *req)
{
	mbx_obj_req o;
	memcpy(&o, req->payload, sizeof o);
	od_read_at(l, req, o.index, o.sub);
}

static void od_write_at(line *l, const mbx_request *req, uint16_t index, uint8_t sub,
			bool trigger_pdo)
{
	uint32_t abort = 0;
	co_od_entry *e = co_od_find_ex(co_node_od(l->node), index, sub, &abort);
	if (!e)
		return line_answer(l, &req->reply, MBX_E_ABORT, abort, NULL, 0);
	if (!(e->access & CO_ACC_WRITE) || (e->access & CO_ACC_CONST))
		return line_answer(l, &req->reply, MBX_E_ABORT, SDO_AB_READ_ONLY, NULL, 0);
	line_app_obj *o = line_app_find(l, e);
	if (o) /* a client owns it: it may refuse, or must hear of it */
		return line_app_od_write(l, req, o, trigger_pdo);
	co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL,
			   .data = req->data,
			   .size = (uint32_t)req->data_len };
	abort = co_od_write(e, req->data, (uint32_t)req->data_len, &a);
	if (abort == CO_OD_DEFERRED)
		abort = SDO_AB_LOCAL_CTRL; /* a local write cannot wait */
	if (abort)
		return line_answer(l, &req->reply, MBX_E_ABORT, abort, NULL, 0);
	if (trigger_pdo)
		co_pdo_object_changed(l->node, index, sub, l->now_us);
	line_answer(l, &req->reply, 0, 0, NULL, 0);
}

static void od_write(line *l, const mbx_request *req, bool trigger_pdo)
{
	mbx_obj_req o;
	memcpy(&o, req->payload, sizeof o);
	od_write_at(l, req, o.index, o.sub, trigger_pdo && (o.flags & MBX_PDO_TRIGGER));
}

void line_od_write(line *l, const mbx_request *req)
{
	od_write(l, req, false);
}

void line_pdo_write(line *l, const mbx_request *req)
{
	od_write(l, req, true);
}

/* An SDO transfer addressed to the line's own node-ID: the line's own
 * object dictionary answers, as OD_READ / OD_WRITE would. The frames of
 * such a transfer would never come back (the kernel does not loop a
 * node's frames to itself), yet the node is an ordinary target to a
 * 309-3 gateway or a routed request: its objects are there to read. */
void line_od_sdo_own(line *l, const mbx_request *req, uint16_t index, uint8_t sub, bool upload)
{
	if (upload)
		od_read_at(l, req, index, sub);
	else
		od_write_at(l, req, index, sub, false);
}

void line_pdo_request(line *l, const mbx_request *req)
{
	mbx_pdo_num_req p;
	memcpy(&p, req->payload, sizeof p);
	int rc = co_pdo_tpdo_event(l->node, p.pdo, l->now_us);
	line_answer(l, &req->reply, mbx_status_of_errno(rc), 0, NULL, 0);
}
