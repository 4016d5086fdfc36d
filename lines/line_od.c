/* SPDX-License-Identifier: MIT */
/*
 * lines/line_od.c - mailbox commands on the line's own object dictionary:
 * OD_READ / OD_WRITE, and their PDO variants (PDO_READ, PDO_WRITE with an
 * optional TPDO trigger, PDO_REQUEST). Answered at once; what is checked
 * here is what only the line knows (does the object exist, may it be read
 * or written).
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <string.h>

#include "core/pdo.h"
#include "core/sdo.h"

void line_od_read(line *l, const mbx_request *req)
{
	mbx_obj_req o;
	memcpy(&o, req->payload, sizeof o);
	uint32_t abort = 0;
	co_od_entry *e = co_od_find_ex(co_node_od(l->node), o.index, o.sub, &abort);
	if (!e)
		return line_answer(l, &req->reply, MBX_E_ABORT, abort, NULL, 0);
	if (!(e->access & CO_ACC_READ))
		return line_answer(l, &req->reply, MBX_E_ABORT, SDO_AB_WRITE_ONLY, NULL, 0);
	line_answer(l, &req->reply, 0, 0, e->data, e->size);
}

static void od_write(line *l, const mbx_request *req, bool trigger_pdo)
{
	mbx_obj_req o;
	memcpy(&o, req->payload, sizeof o);
	uint32_t abort = 0;
	co_od_entry *e = co_od_find_ex(co_node_od(l->node), o.index, o.sub, &abort);
	if (!e)
		return line_answer(l, &req->reply, MBX_E_ABORT, abort, NULL, 0);
	if (!(e->access & CO_ACC_WRITE) || (e->access & CO_ACC_CONST))
		return line_answer(l, &req->reply, MBX_E_ABORT, SDO_AB_READ_ONLY, NULL, 0);
	co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL,
			   .data = req->data,
			   .size = (uint32_t)req->data_len };
	abort = co_od_write(e, req->data, (uint32_t)req->data_len, &a);
	if (abort == CO_OD_DEFERRED)
		abort = SDO_AB_LOCAL_CTRL; /* a local write cannot wait */
	if (abort)
		return line_answer(l, &req->reply, MBX_E_ABORT, abort, NULL, 0);
	if (trigger_pdo && (o.flags & MBX_PDO_TRIGGER))
		co_pdo_object_changed(l->node, o.index, o.sub, l->now_us);
	line_answer(l, &req->reply, 0, 0, NULL, 0);
}

void line_od_write(line *l, const mbx_request *req)
{
	od_write(l, req, false);
}

void line_pdo_write(line *l, const mbx_request *req)
{
	od_write(l, req, true);
}

void line_pdo_request(line *l, const mbx_request *req)
{
	mbx_pdo_num_req p;
	memcpy(&p, req->payload, sizeof p);
	int rc = co_pdo_tpdo_event(l->node, p.pdo, l->now_us);
	line_answer(l, &req->reply, mbx_status_of_errno(rc), 0, NULL, 0);
}
