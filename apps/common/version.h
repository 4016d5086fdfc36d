/* SPDX-License-Identifier: MIT */
/*
 * apps/common/version.h - the release number every program reports with
 * --version; it comes from the file VERSION through the build
 * (build/gen/version.c), so that programs, cogw.pc and the packages agree.
 */
#ifndef COGW_APPS_COMMON_VERSION_H
#define COGW_APPS_COMMON_VERSION_H

#include <stdbool.h>

extern const char cogw_version[];

/* True, after printing "<program> <version>" on stdout, when an argument
 * before "--" is --version: the caller then exits 0. Programs with
 * subcommands (cogwctl) look for it among their own options instead. */
bool cogw_version_asked(const char *program, int argc, char **argv);

#endif /* COGW_APPS_COMMON_VERSION_H */
