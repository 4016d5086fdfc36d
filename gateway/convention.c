/* SPDX-License-Identifier: MIT */
/*
 * gateway/convention.c - encoders and decoders of the project's CiA 302-7
 * conventions (see convention.h for the layouts).
 */
#include "gateway/convention.h"

#include <errno.h>
#include <string.h>

#include "core/frame.h"

uint32_t gw_netind_decode(const uint8_t d[8], gw_netind *out)
{
	out->net = co_get_le16(&d[1]);
	out->node = d[3];
	if (d[0] != GW_NETIND_CS || d[4] || d[5] || d[6] || d[7])
		return SDO_AB_CMD;
	if (out->net < GW_NET_MIN || out->net > GW_NET_MAX)
		return GW_AB_NET_UNKNOWN;
	if (out->node < 1 || out->node > 127)
		return GW_AB_NO_ANSWER;
	return 0;
}

void gw_netind_encode(uint8_t d[8], gw_netind ni)
{
	memset(d, 0, 8);
	d[0] = GW_NETIND_CS;
	co_put_le16(&d[1], ni.net);
	d[3] = ni.node;
}

void gw_sdo_abort_encode(uint8_t d[8], const uint8_t mux[3], uint32_t code)
{
	d[0] = SDO_CCS_ABORT << 5;
	memcpy(&d[1], mux, 3);
	co_put_le32(&d[4], code);
}

void gw_netind_abort_encode(uint8_t d[8], gw_netind ni, uint32_t code)
{
	const uint8_t mux[3] = { (uint8_t)ni.net, (uint8_t)(ni.net >> 8), ni.node };

	gw_sdo_abort_encode(d, mux, code);
}

uint32_t gw_route_entry_encode(gw_route_entry e)
{
	if (!e.reachable)
		return 0;
	return (uint32_t)(e.line + 1u) | ((uint32_t)e.router << 8);
}

uint32_t gw_route_entry_decode(uint32_t v, uint8_t n_lines, gw_route_entry *out)
{
	uint8_t line1 = (uint8_t)v;
	uint8_t router = (uint8_t)(v >> 8);

	memset(out, 0, sizeof(*out));
	if (v >> 16)
		return SDO_AB_VALUE;
	if (router > 127)
		return SDO_AB_VALUE;
	if (line1 == 0)
		return router ? SDO_AB_VALUE : 0;
	if (line1 > n_lines)
		return SDO_AB_VALUE;
	out->reachable = true;
	out->line = (uint8_t)(line1 - 1u);
	out->router = router;
	return 0;
}

void gw_emcy_fwd_encode(uint8_t d[8], const gw_emcy_fwd *e)
{
	co_put_le16(&d[0], GW_EMCY_FWD_CODE);
	d[2] = e->err_reg;
	co_put_le16(&d[3], e->src_net);
	d[5] = e->src_node;
	co_put_le16(&d[6], e->code);
}

int gw_emcy_fwd_decode(const uint8_t d[8], gw_emcy_fwd *out)
{
	if (co_get_le16(&d[0]) != GW_EMCY_FWD_CODE)
		return -EINVAL;
	out->err_reg = d[2];
	out->src_net = co_get_le16(&d[3]);
	out->src_node = d[5];
	out->code = co_get_le16(&d[6]);
	return 0;
}
