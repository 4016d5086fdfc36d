/* SPDX-License-Identifier: MIT */
/*
 * cogwctl - the command-line client of cogwd. Every subcommand is a thin
 * layer over one or two libcogw calls (mailbox/cogw.h); what it adds is
 * strict argument checking, readable output (or --json for scripts) and
 * exit codes a shell script can act on. docs/cogwctl.md is the manual.
 */
#include <stdlib.h>
#include <string.h>

#include "apps/cogwctl/ctl.h"
#include "apps/common/version.h"

static const ctl_cmd *const commands[] = {
	&ctl_cmd_status,    &ctl_cmd_sdo,     &ctl_cmd_od,      &ctl_cmd_nmt,    &ctl_cmd_pdo,
	&ctl_cmd_emcy,      &ctl_cmd_lss,     &ctl_cmd_monitor, &ctl_cmd_raw,    &ctl_cmd_dcf,
	&ctl_cmd_route,     &ctl_cmd_manager, &ctl_cmd_boot,    &ctl_cmd_diag,   &ctl_cmd_program,
	&ctl_cmd_configure, &ctl_cmd_watch,   &ctl_cmd_dev,     &ctl_cmd_health, &ctl_cmd_node,
	&ctl_cmd_app,       &ctl_cmd_host,    &ctl_cmd_scan,
};
#define N_COMMANDS (sizeof commands / sizeof commands[0])

static void overview(FILE *to)
{
	fprintf(to,
		"usage: cogwctl [GLOBAL OPTIONS] COMMAND [ARGS] [OPTIONS]\n"
		"\n"
		"Talks to the cogw daemon (cogwd) through its mailbox; never touches CAN itself.\n"
		"LINE is the daemon's CAN line number (0 = the first line of its configuration),\n"
		"NODE a CANopen node-ID 1..127, INDEX hex (1018 or 0x1018), SUB 0..255.\n"
		"\n"
		"Commands:\n");
	for (size_t i = 0; i < N_COMMANDS; i++)
		fprintf(to, "%s", commands[i]->synopsis);
	fprintf(to,
		"\n"
		"Global options (accepted before or after the command):\n"
		"  --instance NAME  mailbox instance of the daemon (default: $COGW_INSTANCE, else "
		"\"main\")\n"
		"  --timeout MS     how long to wait for each answer of the daemon (default 5000)\n"
		"  --json           machine-readable output: one JSON object per result or event\n"
		"  --help, -h       this text; 'cogwctl COMMAND --help' explains one command\n"
		"  --version        print the version\n"
		"\n"
		"Exit status:\n"
		"  0  success\n"
		"  1  refused: SDO abort (code and meaning printed), LSS error, the daemon "
		"refused\n"
		"  2  usage error (bad command line or value)\n"
		"  3  daemon not reachable (no cogwd for this instance, or no such line)\n"
		"  4  timeout: the daemon or the device did not answer in time; the message\n"
		"     says which (\"the daemon did not answer\" / \"the device did not answer\";\n"
		"     --json: \"timeout\": \"daemon\" or \"device\"). An SDO abort 0x05040000\n"
		"     \"SDO protocol timed out\" is a device timeout\n"
		"\n"
		"Manual: docs/cogwctl.md\n");
}

/* stdout's buffer, given before the first output: stdio would otherwise
 * fstat and ioctl stdout to choose one (two system calls of every one-shot
 * command, docs/fastpath.md "One-shot `cogwctl`"). Line-buffered as on a
 * terminal, also into pipes and files: every line reaches a reader when
 * it is printed (monitor and watch flush each event line already). */
static char stdout_buffer[BUFSIZ];

int main(int argc, char **argv)
{
	ctl c = { .instance = "main", .timeout_ms = 0 };
	setvbuf(stdout, stdout_buffer, _IOLBF, sizeof stdout_buffer);
	const char *env = getenv("COGW_INSTANCE");
	if (env && *env) {
		if (!mbx_instance_is_valid(env)) {
			fprintf(stderr,
				"cogwctl: $COGW_INSTANCE '%s' is not a valid instance name\n", env);
			return CTL_EXIT_USAGE;
		}
		c.instance = env;
	}

	int i = 1;
	for (; i < argc; i++) {
		if (strcmp(argv[i], "--version") == 0) {
			printf("cogwctl %s (mailbox protocol %u)\n", cogw_version, MBX_VERSION);
			return CTL_EXIT_OK;
		}
		if (argv[i][0] != '-')
			break;
		int g = ctl_global_option(&c, argc, argv, &i);
		if (g < 0)
			return CTL_EXIT_USAGE;
		if (g == 0) {
			fprintf(stderr, "cogwctl: unknown option '%s'\n", argv[i]);
			overview(stderr);
			return CTL_EXIT_USAGE;
		}
	}
	if (i >= argc) {
		if (c.help) {
			overview(stdout);
			return CTL_EXIT_OK;
		}
		fprintf(stderr, "cogwctl: no command given\n");
		overview(stderr);
		return CTL_EXIT_USAGE;
	}
	if (strcmp(argv[i], "help") == 0) {
		if (i + 1 < argc)
			for (size_t k = 0; k < N_COMMANDS; k++)
				if (strcmp(argv[i + 1], commands[k]->name) == 0)
					return ctl_print_help(commands[k]);
		overview(stdout);
		return CTL_EXIT_OK;
	}
	for (size_t k = 0; k < N_COMMANDS; k++) {
		if (strcmp(argv[i], commands[k]->name) != 0)
			continue;
		c.what = commands[k]->name;
		int rc = commands[k]->run(&c, argc - i, argv + i);
		cogw_close(c.h);
		return rc;
	}
	fprintf(stderr, "cogwctl: unknown command '%s'\n", argv[i]);
	overview(stderr);
	return CTL_EXIT_USAGE;
}
