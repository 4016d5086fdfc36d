/* SPDX-License-Identifier: MIT */
/*
 * manager/manager_adopt.c - see manager_adopt.h. The objects are those a
 * configuration tool would write to add a node (CiA 302-2 1F81h,
 * 1F84h..1F88h; CiA 302-3 1F22h), so the boot that follows is the
 * ordinary boot slave process: device type and identity checked, the
 * concise DCF downloaded, error control started, the node started.
 */
#include "manager/manager_adopt.h"

#include <errno.h>

#include "core/cfgmgr.h"

static bool field_matches(uint32_t want, uint32_t have)
{
	return !want || want == have;
}

const mgr_ext_device *mgr_adopt_match(const mgr_ext_device *devs, size_t n, const uint32_t ident[4])
{
	for (size_t i = 0; i < n; i++) {
		const uint32_t *w = devs[i].ident;
		/* 1000h: the profile (low 16 bits) and its additional
		 * information as the file says */
		if (field_matches(w[0], ident[0]) && field_matches(w[1], ident[1]) &&
		    field_matches(w[2], ident[2]) && field_matches(w[3], ident[3]))
			return &devs[i];
	}
	return NULL;
}

int mgr_adopt_boot(co_manager *m, co_node *node, uint8_t node_id, const mgr_ext_device *dev,
		   const uint32_t ident[4], uint64_t now_us)
{
	co_od *od = co_node_od(node);
	static const uint16_t expected[4] = { 0x1F84, 0x1F85, 0x1F86, 0x1F87 };
	int rc;
	if (node_id < 1 || node_id > 127 || !dev->cdcf[node_id])
		return -EINVAL;
	if ((rc = co_od_set_bytes(od, CO_CFGMGR_IDX_CDCF, node_id, dev->cdcf[node_id],
				  (uint32_t)dev->cdcf_len[node_id])) < 0)
		return rc;
	for (unsigned i = 0; i < 4; i++)
		if ((rc = co_od_set_u32(od, expected[i], node_id, ident[i])) < 0)
			return rc;
	if ((rc = co_od_set_u32(od, 0x1F88, node_id, 0)) < 0 ||
	    (rc = co_od_set_u32(od, 0x1F81, node_id, CO_MGR_1F81_SLAVE | CO_MGR_1F81_BOOT)) < 0)
		return rc;
	return co_manager_boot_node(m, node_id, now_us);
}
