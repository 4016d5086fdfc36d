/* SPDX-License-Identifier: MIT */
/*
 * apps/cogwd/manager_ext.h - the CiA 302-2 manager (core/manager.h), with
 * the CiA 302-3 configuration manager (core/cfgmgr.h) as its configure
 * step, on every line whose configuration has a "manager" section: a line
 * extension (lines/line_ext.h) that feeds the line's core events and time
 * to them, publishes their events on the mailbox (classes BOOT and
 * MANAGER) and answers the MBX_CMD_MGR_* commands.
 */
#ifndef COGW_APPS_COGWD_MANAGER_EXT_H
#define COGW_APPS_COGWD_MANAGER_EXT_H

#include "apps/cogwd/extensions.h"

extern const cogwd_ext_provider cogwd_manager_provider;

#endif
