/* SPDX-License-Identifier: MIT */
/*
 * lines/line_dispatch.c - where a mailbox command goes on the line thread.
 * The mailbox server has already validated the envelope, the payload
 * fields and the client's access. An extension that claims the code
 * (line_ext.h) gets it first; otherwise the table below names the one
 * function, in the one file, that carries the command out and answers it
 * (at once, or from its completion in the same file).
 */
#include "lines/line_internal.h"

#include <stddef.h>

static const struct {
	uint16_t code;
	line_cmd_fn fn;
} commands[] = {
	{ MBX_CMD_OD_READ, line_od_read }, /* line_od.c */
	{ MBX_CMD_OD_WRITE, line_od_write },
	{ MBX_CMD_PDO_READ, line_od_read },
	{ MBX_CMD_PDO_WRITE, line_pdo_write },
	{ MBX_CMD_PDO_REQUEST, line_pdo_request },
	{ MBX_CMD_RPDO_STATUS, line_rpdo_status }, /* line_pdo.c */
	{ MBX_CMD_SDO_UPLOAD, line_sdo_upload },   /* line_sdo.c */
	{ MBX_CMD_SDO_DOWNLOAD, line_sdo_download },
	{ MBX_CMD_GW_SDO_UPLOAD, line_sdo_upload_net },
	{ MBX_CMD_GW_SDO_DOWNLOAD, line_sdo_download_net },
	{ MBX_CMD_NMT, line_nmt_command }, /* line_nmt.c */
	{ MBX_CMD_NODE_TABLE, line_node_table },
	{ MBX_CMD_NODE_SCAN, line_scan_command }, /* line_scan.c */
	{ MBX_CMD_NODE_SCAN_CACHE, line_scan_cache_command },
	{ MBX_CMD_LINE_STATUS, line_status }, /* line_bus.c */
	{ MBX_CMD_LINE_HEALTH, line_health }, /* line_health.c */
	{ MBX_CMD_LINE_HEALTH_RESET, line_health_reset },
	{ MBX_CMD_EMCY_SEND, line_emcy_send },
	{ MBX_CMD_RAW_SEND, line_raw_send },
	{ MBX_CMD_STORE, line_store_command }, /* line_store.c */
	{ MBX_CMD_RESTORE, line_store_command },
	{ MBX_CMD_LSS_SWITCH_GLOBAL, line_lss_command }, /* line_lss.c */
	{ MBX_CMD_LSS_SWITCH_SELECTIVE, line_lss_command },
	{ MBX_CMD_LSS_SET_NODE_ID, line_lss_command },
	{ MBX_CMD_LSS_SET_BIT_TIMING, line_lss_command },
	{ MBX_CMD_LSS_ACTIVATE_BIT_TIMING, line_lss_command },
	{ MBX_CMD_LSS_STORE, line_lss_command },
	{ MBX_CMD_LSS_INQUIRE, line_lss_command },
	{ MBX_CMD_LSS_IDENTIFY_REMOTE, line_lss_command },
	{ MBX_CMD_LSS_IDENTIFY_NONCONF, line_lss_command },
	{ MBX_CMD_LSS_FASTSCAN, line_lss_command },
	{ MBX_CMD_APP_CLAIM, line_app_claim }, /* line_app.c */
	{ MBX_CMD_APP_RELEASE, line_app_release },
	{ MBX_CMD_APP_LIST, line_app_list },
	{ MBX_CMD_APP_ANSWER, line_app_answer }, /* line_app_ind.c */
	{ MBX_CMD_APP_IND_DATA, line_app_ind_data },
	{ MBX_CMD_APP_WATCHDOG, line_appwd_command }, /* line_appwd.c */
	{ MBX_CMD_APP_KEEPALIVE, line_appwd_command },
	{ MBX_CMD_APP_HOLD, line_appwd_command },
	{ MBX_CMD_HOST_READY, line_appwd_command },
	{ MBX_CMD_APP_STATUS, line_appwd_command },
};

void line_dispatch(void *ctx, mbx_server *srv, const mbx_request *req)
{
	line *l = ctx;
	(void)srv;
	/* the interface is down: no request waits for a bus it cannot reach
	 * (lines/line_link.c) */
	if (line_link_refuses(l, req->code))
		return line_answer(l, &req->reply, MBX_E_STATE, 0, NULL, 0);
	/* the host is not ready: the line's nodes and safe outputs are left
	 * alone (lines/line_appwd.c) */
	if (line_appwd_refuses(l, req))
		return line_answer(l, &req->reply, MBX_E_STATE, 0, NULL, 0);
	for (unsigned i = 0; i < l->ext_attached; i++) {
		const line_ext *x = &l->p.ext[i];
		if (x->ops && x->ops->on_command && x->ops->cmd_last &&
		    req->code >= x->ops->cmd_first && req->code <= x->ops->cmd_last)
			return x->ops->on_command(x->ctx, l, req);
	}
	for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
		if (commands[i].code == req->code)
			return commands[i].fn(l, req);
	line_answer(l, &req->reply, MBX_E_UNSUPPORTED, 0, NULL, 0);
}

void line_client_gone(void *ctx, mbx_server *srv, uint32_t client)
{
	line *l = ctx;
	(void)srv;
	line_sdo_client_gone(l, client);
	line_lss_client_gone(l, client);
	line_app_client_gone(l, client);
	line_appwd_client_gone(l, client);
	for (unsigned i = 0; i < l->ext_attached; i++) {
		const line_ext *x = &l->p.ext[i];
		if (x->ops && x->ops->on_client_gone)
			x->ops->on_client_gone(x->ctx, l, client);
	}
}
