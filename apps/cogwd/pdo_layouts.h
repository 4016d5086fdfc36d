/* SPDX-License-Identifier: MIT */
/*
 * apps/cogwd/pdo_layouts.h - the table of learned PDO layouts of one line
 * (core/pdo_layout.h), made from its configuration before the line exists:
 * room for every node that is scanned or has a file layout (lines[]
 * .pdo_scan_max PDOs per direction), the file layouts filled in (source
 * FILE, one log line per PDO). The line gets it in line_params.pdo_layout;
 * cogwd destroys it after the line. A reload cannot change what it is made
 * from (nodes, pdo, pdo_scan_max need a restart: docs/config.md "Reload").
 *
 * Main thread, start-up only.
 */
#ifndef COGW_APPS_COGWD_PDO_LAYOUTS_H
#define COGW_APPS_COGWD_PDO_LAYOUTS_H

#include <stdint.h>

#include "apps/common/config.h"
#include "core/pdo_layout.h"

/* *out NULL when no node of the line has a place in it. -ENOMEM. */
int cogwd_pdo_layouts_create(co_pdo_layout **out, const cogw_line_config *lc, uint64_t now_us);

#endif /* COGW_APPS_COGWD_PDO_LAYOUTS_H */
