/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_api_app.c - libcogw, objects a client owns on a line's own
 * node (docs/application.md): claiming, creating and releasing them,
 * answering their indications, the line's table of them. Each call is one
 * request and its answer through client_call() (mailbox/client_internal.h);
 * the indications themselves arrive as events (cogw_recv, cogw_loop_recv)
 * and are read with the parsers below. A held object's value is written
 * with cogw_od_write / cogw_pdo_write like any object of the line.
 */
#include "mailbox/client_internal.h"

#include <string.h>

int cogw_app_claim(cogw *h, unsigned line, const mbx_app_claim_req *obj, const void *def,
		   size_t def_len, unsigned timeout_ms)
{
	return client_call(h, line, MBX_CMD_APP_CLAIM, obj, sizeof *obj, def, def_len, NULL, 0,
			   NULL, NULL, timeout_ms);
}

int cogw_app_release(cogw *h, unsigned line, uint16_t index, uint8_t sub, unsigned timeout_ms)
{
	mbx_obj_req r = { .index = index, .sub = sub };

	return client_call(h, line, MBX_CMD_APP_RELEASE, &r, sizeof r, NULL, 0, NULL, 0, NULL, NULL,
			   timeout_ms);
}

int cogw_app_answer(cogw *h, unsigned line, uint32_t ind, uint32_t abort, const void *data,
		    size_t len, unsigned timeout_ms)
{
	mbx_app_answer_req r = { .ind = ind, .abort = abort };

	return client_call(h, line, MBX_CMD_APP_ANSWER, &r, sizeof r, data, len, NULL, 0, NULL,
			   NULL, timeout_ms);
}

int cogw_app_ind_data(cogw *h, unsigned line, uint32_t ind, void *buf, size_t cap, size_t *len,
		      unsigned timeout_ms)
{
	mbx_app_ind_req r = { .ind = ind };

	return client_call(h, line, MBX_CMD_APP_IND_DATA, &r, sizeof r, NULL, 0, buf, cap, len,
			   NULL, timeout_ms);
}

int cogw_app_list(cogw *h, unsigned line, mbx_app_status *st, mbx_app_obj *objs, size_t cap,
		  size_t *n, unsigned timeout_ms)
{
	uint8_t buf[sizeof *st + 256 * sizeof *objs];
	size_t len = 0;
	int rc = client_call(h, line, MBX_CMD_APP_LIST, NULL, 0, NULL, 0, buf, sizeof buf, &len,
			     NULL, timeout_ms);

	if (rc < 0 && rc != COGW_E_TRUNCATED)
		return rc;
	if (len > sizeof buf)
		len = sizeof buf; /* more objects than 256: the first ones */
	if (len < sizeof *st || (len - sizeof *st) % sizeof *objs)
		return COGW_E_PROTOCOL;
	memcpy(st, buf, sizeof *st);
	size_t got = (len - sizeof *st) / sizeof *objs;
	*n = got < cap ? got : cap;
	if (*n)
		memcpy(objs, buf + sizeof *st, *n * sizeof *objs);
	return got > cap || st->n > got ? COGW_E_TRUNCATED : 0;
}

int cogw_app_ind_parse(const void *payload, size_t len, mbx_ev_app_ind *ind, const uint8_t **data)
{
	return mbx_app_event_split(MBX_EV_APP_IND, payload, len, ind, data) ? COGW_E_PROTOCOL : 0;
}

int cogw_app_written_parse(const void *payload, size_t len, mbx_ev_app_written *w,
			   const uint8_t **data)
{
	return mbx_app_event_split(MBX_EV_APP_WRITTEN, payload, len, w, data) ? COGW_E_PROTOCOL : 0;
}
