/* SPDX-License-Identifier: MIT */
/*
 * manager/manager_adopt.h - a node outside the configuration taken as an
 * optional slave (docs/config.md "unknown_nodes", policy "boot"): the
 * device file its identity matches gives its concise DCF (1F22h:n), the
 * identity read becomes the expected one (1F84h..1F87h:n), 1F81h:n says
 * "slave, may be booted", and the manager boots it (CiA 302-2). Line
 * thread only; no allocation (1F22h:n has its room from the start-up).
 */
#ifndef COGW_MANAGER_MANAGER_ADOPT_H
#define COGW_MANAGER_MANAGER_ADOPT_H

#include <stddef.h>
#include <stdint.h>

#include "core/co.h"
#include "core/manager.h"

/* A device file of the directory: its identity (0 = any) and its concise
 * DCF by node-ID. Must outlive the extension. */
typedef struct mgr_ext_device {
	const char *file;
	uint32_t ident[4]; /* 1000h, 1018h:1..3 */
	uint8_t *const *cdcf;
	const size_t *cdcf_len; /* [128] both */
} mgr_ext_device;

/* The first device whose identity matches ident (1000h, 1018h:1..3 read
 * from the node), or NULL. */
const mgr_ext_device *mgr_adopt_match(const mgr_ext_device *devs, size_t n,
				      const uint32_t ident[4]);
/* Write node's objects from dev and ident and boot it: 0, or -errno
 * (-EPERM: the manager does not run; -EMSGSIZE: no room in 1F22h:n). */
int mgr_adopt_boot(co_manager *m, co_node *node, uint8_t node_id, const mgr_ext_device *dev,
		   const uint32_t ident[4], uint64_t now_us);

#endif /* COGW_MANAGER_MANAGER_ADOPT_H */
