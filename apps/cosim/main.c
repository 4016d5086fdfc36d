/* SPDX-License-Identifier: MIT */
/*
 * apps/cosim/main.c - cosim, simulated CANopen slave devices on a SocketCAN
 * line (docs/cosim.md).
 *
 * One thread, one epoll loop, Redis-ae style: the CAN socket, one timerfd
 * armed at the earliest deadline of all nodes, a signalfd and the control
 * socket. The clock is read once per iteration and handed to every call.
 *
 * Several nodes share one socket. The kernel does not loop a socket's own
 * frames back to it, so frames one local node sends are also delivered to
 * the other local nodes here, as they would be on a real bus. They go
 * through a queue drained after each handler, never by a direct call from
 * one node's send callback into another node (which could then answer
 * into the first node while it is still inside its own call).
 */
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <signal.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <sys/timerfd.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include "apps/common/version.h"
#include "apps/cosim/cosim.h"
#include "core/nmt.h"
#include "lines/socketcan.h"

#define MAX_NODES 16
#define LOCAL_QUEUE 1024

enum exit_code {
	EXIT_OK = 0,
	EXIT_RUNTIME = 1, /* CAN socket failed while running, epoll, ... */
	EXIT_USAGE = 2,   /* bad command line */
	EXIT_DEVICE = 3,  /* a device file or its stored values are bad */
	EXIT_CAN = 4,     /* the CAN interface cannot be opened */
};

struct local_frame {
	co_frame f;
	int from;
};

struct dev_arg {
	const char *file;
	cosim_device_opts opts;
};

struct app {
	can_port *port;
	cosim_node *nodes[MAX_NODES];
	int n_nodes;
	struct local_frame local[LOCAL_QUEUE];
	unsigned local_head, local_count;
	uint64_t local_dropped;
	bool quiet;
	bool quit;
};

static uint64_t mono_us(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static int node_index(const struct app *a, const cosim_node *n)
{
	for (int i = 0; i < a->n_nodes; i++)
		if (a->nodes[i] == n)
			return i;
	return -1;
}

/* cosim_out_fn: one node's frame leaves for the bus and the other nodes. */
static int out_frame(void *ctx, cosim_node *from, const co_frame *f, uint64_t now_us)
{
	struct app *a = ctx;
	int rc = can_port_send(a->port, f, now_us);

	if (a->n_nodes > 1) {
		if (a->local_count == LOCAL_QUEUE) {
			a->local_dropped++;
		} else {
			struct local_frame *l =
				&a->local[(a->local_head + a->local_count) % LOCAL_QUEUE];
			l->f = *f;
			/* nodes[] is filled while nodes are created; a node
			 * sends nothing before its first tick */
			l->from = node_index(a, from);
			a->local_count++;
		}
	}
	return rc;
}

static void drain_local(struct app *a, uint64_t now_us)
{
	/* Bounded: a pathological echo between two nodes cannot spin. */
	for (unsigned budget = 4 * LOCAL_QUEUE; a->local_count && budget; budget--) {
		struct local_frame l = a->local[a->local_head];
		a->local_head = (a->local_head + 1) % LOCAL_QUEUE;
		a->local_count--;
		for (int i = 0; i < a->n_nodes; i++)
			if (i != l.from)
				cosim_node_recv(a->nodes[i], &l.f, now_us);
	}
}

static void run_timers(struct app *a, uint64_t now_us)
{
	/* A tick may make another node's deadline due (local frames), so go
	 * round until nothing is due at this time. */
	for (int round = 0; round < 8; round++) {
		bool any = false;
		for (int i = 0; i < a->n_nodes; i++) {
			if (cosim_node_next_deadline(a->nodes[i]) <= now_us) {
				cosim_node_tick(a->nodes[i], now_us);
				any = true;
			}
		}
		drain_local(a, now_us);
		if (!any)
			break;
	}
}

static void arm_timer(struct app *a, int tfd, uint64_t now_us)
{
	uint64_t t = can_port_retry_at_us(a->port);
	struct itimerspec its = { 0 };

	for (int i = 0; i < a->n_nodes; i++) {
		uint64_t d = cosim_node_next_deadline(a->nodes[i]);
		if (d < t)
			t = d;
	}
	if (t != UINT64_MAX) {
		if (t <= now_us)
			t = now_us + 1; /* a zero it_value would disarm */
		its.it_value.tv_sec = (time_t)(t / 1000000u);
		its.it_value.tv_nsec = (long)(t % 1000000u) * 1000;
	}
	timerfd_settime(tfd, TFD_TIMER_ABSTIME, &its, NULL);
}

static int handle_can(struct app *a, uint64_t now_us)
{
	can_rx_item items[32];
	int n;

	while ((n = can_port_recv(a->port, items, 32, now_us)) > 0) {
		for (int k = 0; k < n; k++) {
			if (items[k].is_error) {
				if (items[k].error.state_changed)
					cosim_log(a->quiet, "CAN controller %s",
						  can_bus_state_to_string(items[k].error.state));
				continue;
			}
			for (int i = 0; i < a->n_nodes; i++)
				cosim_node_recv(a->nodes[i], &items[k].frame, now_us);
			drain_local(a, now_us);
		}
		if (n < 32)
			break;
	}
	if (n == -ENETDOWN) {
		/* The interface went down (ip link set ... down): a device on
		 * that bus waits for it to come back, as a real one would. */
		cosim_log(a->quiet, "CAN interface down");
	} else if (n < 0 && n != -EAGAIN) {
		cosim_log(false, "CAN receive failed: %s", strerror(-n));
		return n;
	}
	can_port_flush(a->port, now_us);
	return 0;
}

/* cmd for every node (only < 0) or node `only`: their answers, "; "
 * between them, into reply. */
static void command_nodes(struct app *a, const char *cmd, int only, uint64_t now_us, char *reply,
			  size_t rl)
{
	char one[256];
	size_t used = 0;

	if (!strcmp(cmd, "quit")) {
		a->quit = true;
		snprintf(reply, rl, "ok quit");
		return;
	}
	for (int i = 0; i < a->n_nodes; i++) {
		cosim_node *n = a->nodes[i];
		if (only >= 0 && cosim_node_config_id(n) != only &&
		    co_node_id(cosim_node_core(n)) != only)
			continue;
		cosim_node_command(n, cmd, now_us, one, sizeof one);
		int k = snprintf(reply + used, rl - used, "%s%s", used ? "; " : "", one);
		if (k > 0 && (size_t)k < rl - used)
			used += (size_t)k;
	}
	if (!used)
		snprintf(reply, rl, "error: no node %d here", only);
	drain_local(a, now_us);
}

/* One datagram = one command, optionally "node N <command>". */
static void handle_control(struct app *a, int cfd, uint64_t now_us)
{
	char buf[512], reply[1024];
	struct sockaddr_un from;
	socklen_t flen = sizeof from;
	ssize_t len = recvfrom(cfd, buf, sizeof buf - 1, MSG_DONTWAIT, (struct sockaddr *)&from,
			       &flen);
	const char *cmd = buf;
	int only = -1;

	if (len < 0)
		return;
	buf[len] = 0;
	while (len > 0 && (buf[len - 1] == '\n' || buf[len - 1] == '\r'))
		buf[--len] = 0;
	reply[0] = 0;
	if (!strncmp(cmd, "node ", 5)) {
		char *end;
		long id = strtol(cmd + 5, &end, 10);
		if (end == cmd + 5 || *end != ' ' || id < 1 || id > 255)
			snprintf(reply, sizeof reply, "error: node N COMMAND");
		only = (int)id;
		cmd = end + 1;
	}
	if (!reply[0])
		command_nodes(a, cmd, only, now_us, reply, sizeof reply);
	cosim_log(a->quiet, "control: %s -> %s", buf, reply);
	if (flen > sizeof(sa_family_t))
		sendto(cfd, reply, strlen(reply), MSG_DONTWAIT, (struct sockaddr *)&from, flen);
}

static int open_control(const char *path)
{
	struct sockaddr_un sa = { .sun_family = AF_UNIX };
	int fd;

	if (strlen(path) >= sizeof sa.sun_path) {
		errno = ENAMETOOLONG;
		return -1;
	}
	strcpy(sa.sun_path, path);
	fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
	if (fd < 0)
		return -1;
	unlink(path);
	if (bind(fd, (struct sockaddr *)&sa, sizeof sa) < 0) {
		int e = errno;
		close(fd);
		errno = e;
		return -1;
	}
	return fd;
}

static void usage(FILE *out)
{
	fputs("usage: cosim --interface IF --device FILE[:NODE] [--node-id N] [--serial N]\n"
	      "             [--device ...] [options]\n"
	      "\n"
	      "Simulated CANopen slave devices on a SocketCAN line, each described by a\n"
	      "JSON device file (etc/devices/*.json, format in docs/cosim.md).\n"
	      "\n"
	      "Devices (--device may repeat: several nodes in one process):\n"
	      "  -i, --interface IF     CAN interface (vcan0, can0)\n"
	      "  -d, --device FILE[:N]  add a node from FILE, optionally with node-ID N\n"
	      "  -n, --node-id N        node-ID of the last --device (1..127, 255 = LSS\n"
	      "                         unconfigured)\n"
	      "  -s, --serial N         1018h:4 serial number of the last --device\n"
	      "      --nv DIR           non-volatile memory: 1010h \"save\" and LSS store\n"
	      "                         write DIR/<device>-<node>.{comm,app,lss}; the next\n"
	      "                         start loads them\n"
	      "      --autostart        enter OPERATIONAL after boot-up without a master\n"
	      "      --loopback         echo outputs into inputs (device file \"loopback\")\n"
	      "      --sdo-timeout MS   SDO server timeout per frame (default 1000): raise it\n"
	      "                         where the peer can stall for longer (slow test VMs)\n"
	      "\n"
	      "Faults (all nodes; also switchable at run time, see --control):\n"
	      "      --silent           send nothing, hear nothing (cable pulled)\n"
	      "      --hb-stop          no heartbeats (boot-up still goes out)\n"
	      "      --sdo-silent       no SDO answers\n"
	      "      --sdo-abort CODE   answer every SDO request with this abort code\n"
	      "      --sdo-delay MS     send SDO answers MS milliseconds late\n"
	      "      --sdo-lenient      accept printed-sheet frames: too small sizes in\n"
	      "                         expedited writes (2Bh for 4 bytes), reversed \"save\"\n"
	      "      --pdo-badlen       TPDOs one byte short\n"
	      "      SIGUSR1            toggles --hb-stop\n"
	      "\n"
	      "Control:\n"
	      "  -c, --control PATH     UNIX datagram socket for commands, one per datagram,\n"
	      "                         answered \"ok ...\" or \"error: ...\" to the sender:\n"
	      "      hb stop|start            silent on|off\n"
	      "      sdo silent on|off        sdo abort CODE [0xINDEX[:SUB]] | sdo abort off\n"
	      "      sdo delay MS             sdo lenient on|off\n"
	      "      pdo badlen on|off        emcy CODE [REGISTER] | emcy clear\n"
	      "      pressure VALUE|off       signal NAME VALUE|off  (raw signal value)\n"
	      "      set 0xINDEX:SUB VALUE    get 0xINDEX:SUB\n"
	      "      nmt start|stop|preop|reset-node|reset-comm\n"
	      "      loopback on|off          status          quit\n"
	      "      prefix \"node N \" to address one node (default: all)\n"
	      "  -q, --quiet            no log lines on stderr\n"
	      "  -h, --help             this text\n"
	      "\n"
	      "Exit status: 0 clean exit (SIGTERM, SIGINT, quit), 1 runtime failure,\n"
	      "2 bad command line, 3 bad device file or stored values, 4 CAN interface\n"
	      "cannot be opened.\n",
	      out);
}

static bool parse_int(const char *s, long min, long max, long *out)
{
	char *end;
	long v;

	errno = 0;
	v = strtol(s, &end, 0);
	if (errno || end == s || *end || v < min || v > max)
		return false;
	*out = v;
	return true;
}

/* "etc/devices/sti-pressure.json" -> "sti-pressure-1" */
static void nv_key(char *out, size_t n, const char *file, unsigned node)
{
	const char *base = strrchr(file, '/');
	size_t len;

	base = base ? base + 1 : file;
	len = strlen(base);
	if (len > 5 && !strcmp(base + len - 5, ".json"))
		len -= 5;
	if (len > 64)
		len = 64;
	snprintf(out, n, "%.*s-%u", (int)len, base, node);
}

/* ---- command line ------------------------------------------------------ */

struct cmdline {
	const char *ifname, *nv_dir, *control;
	struct dev_arg devs[MAX_NODES];
	int n_devs;
	bool autostart, loopback, quiet;
	uint32_t sdo_timeout_ms; /* 0 = the core's default */
	cosim_faults faults;
};

#define OPT_GO_ON (-1) /* an option handler's "parse the next one" */

struct opt_def;
/* Applies one option; returns OPT_GO_ON or the exit code to stop with. */
typedef int (*opt_apply_fn)(struct cmdline *cl, const struct opt_def *o, const char *arg);

/* One command-line option: its names, how it is applied and, for the
 * generic handlers, which field of struct cmdline it sets and its range. */
struct opt_def {
	const char *name;
	char short_name; /* 0: long form only */
	bool has_arg;
	opt_apply_fn apply;
	size_t field; /* offsetof(struct cmdline, ...) */
	long min, max;
	const char *range; /* "cosim: --NAME ARG: <range>" */
};

#define CMDLINE_FIELD(type, cl, o) ((type *)((char *)(cl) + (o)->field))

static int opt_flag(struct cmdline *cl, const struct opt_def *o, const char *arg)
{
	(void)arg;
	*CMDLINE_FIELD(bool, cl, o) = true;
	return OPT_GO_ON;
}

static int opt_string(struct cmdline *cl, const struct opt_def *o, const char *arg)
{
	*CMDLINE_FIELD(const char *, cl, o) = arg;
	return OPT_GO_ON;
}

static int opt_u32(struct cmdline *cl, const struct opt_def *o, const char *arg)
{
	long v;

	if (!parse_int(arg, o->min, o->max, &v)) {
		fprintf(stderr, "cosim: --%s %s: %s\n", o->name, arg, o->range);
		return EXIT_USAGE;
	}
	*CMDLINE_FIELD(uint32_t, cl, o) = (uint32_t)v;
	return OPT_GO_ON;
}

static int opt_help(struct cmdline *cl, const struct opt_def *o, const char *arg)
{
	(void)cl;
	(void)o;
	(void)arg;
	usage(stdout);
	return EXIT_OK;
}

static int opt_device(struct cmdline *cl, const struct opt_def *o, const char *arg)
{
	long v;

	(void)o;
	if (cl->n_devs == MAX_NODES) {
		fprintf(stderr, "cosim: at most %d devices\n", MAX_NODES);
		return EXIT_USAGE;
	}
	struct dev_arg *d = &cl->devs[cl->n_devs++];
	char *colon = strrchr(arg, ':');
	d->file = arg;
	d->opts.node_id = -1;
	d->opts.serial = -1;
	if (colon && parse_int(colon + 1, 1, 255, &v)) {
		*colon = 0;
		d->opts.node_id = (int)v;
	}
	return OPT_GO_ON;
}

/* --node-id and --serial: a value of the --device before them. */
static struct dev_arg *last_device(struct cmdline *cl, const struct opt_def *o)
{
	if (!cl->n_devs) {
		fprintf(stderr, "cosim: --%s applies to the --device before it\n", o->name);
		return NULL;
	}
	return &cl->devs[cl->n_devs - 1];
}

static int opt_node_id(struct cmdline *cl, const struct opt_def *o, const char *arg)
{
	struct dev_arg *d = last_device(cl, o);
	long v;

	if (!d)
		return EXIT_USAGE;
	if (!parse_int(arg, o->min, o->max, &v) || (v > 127 && v != 255)) {
		fprintf(stderr, "cosim: --%s %s: %s\n", o->name, arg, o->range);
		return EXIT_USAGE;
	}
	d->opts.node_id = (int)v;
	return OPT_GO_ON;
}

static int opt_serial(struct cmdline *cl, const struct opt_def *o, const char *arg)
{
	struct dev_arg *d = last_device(cl, o);
	long v;

	if (!d)
		return EXIT_USAGE;
	if (!parse_int(arg, o->min, o->max, &v)) {
		fprintf(stderr, "cosim: --%s %s: %s\n", o->name, arg, o->range);
		return EXIT_USAGE;
	}
	d->opts.serial = v;
	return OPT_GO_ON;
}

#define F(member) offsetof(struct cmdline, member)

/* Every option of cosim (usage() explains them; docs/cosim.md too). */
static const struct opt_def options[] = {
	{ "interface", 'i', true, opt_string, F(ifname), 0, 0, NULL },
	{ "device", 'd', true, opt_device, 0, 0, 0, NULL },
	{ "node-id", 'n', true, opt_node_id, 0, 1, 255, "1..127 or 255" },
	{ "serial", 's', true, opt_serial, 0, 0, 0xFFFFFFFFL, "0..0xFFFFFFFF" },
	{ "control", 'c', true, opt_string, F(control), 0, 0, NULL },
	{ "quiet", 'q', false, opt_flag, F(quiet), 0, 0, NULL },
	{ "help", 'h', false, opt_help, 0, 0, 0, NULL },
	{ "nv", 0, true, opt_string, F(nv_dir), 0, 0, NULL },
	{ "autostart", 0, false, opt_flag, F(autostart), 0, 0, NULL },
	{ "loopback", 0, false, opt_flag, F(loopback), 0, 0, NULL },
	{ "silent", 0, false, opt_flag, F(faults.silent), 0, 0, NULL },
	{ "hb-stop", 0, false, opt_flag, F(faults.hb_stop), 0, 0, NULL },
	{ "sdo-silent", 0, false, opt_flag, F(faults.sdo_silent), 0, 0, NULL },
	{ "sdo-abort", 0, true, opt_u32, F(faults.sdo_abort), 1, 0xFFFFFFFFL, "an abort code" },
	{ "sdo-delay", 0, true, opt_u32, F(faults.sdo_delay_ms), 0, 600000, "0..600000 ms" },
	{ "sdo-lenient", 0, false, opt_flag, F(faults.sdo_lenient), 0, 0, NULL },
	{ "pdo-badlen", 0, false, opt_flag, F(faults.pdo_badlen), 0, 0, NULL },
	{ "sdo-timeout", 0, true, opt_u32, F(sdo_timeout_ms), 1, 600000, "1..600000 ms" },
};

#undef F

#define N_OPTIONS (sizeof options / sizeof options[0])
#define OPT_INDEX_BASE 256 /* getopt_long's value for options[i]: base + i */

/* Returns OPT_GO_ON when the line is complete and valid, else the exit code. */
static int parse_cmdline(struct cmdline *cl, int argc, char **argv)
{
	struct option longopts[N_OPTIONS + 1];
	char shortopts[2 * N_OPTIONS + 1];
	size_t n_short = 0;
	int opt;

	for (size_t i = 0; i < N_OPTIONS; i++) {
		longopts[i] = (struct option){ options[i].name,
					       options[i].has_arg ? required_argument : no_argument,
					       NULL, OPT_INDEX_BASE + (int)i };
		if (options[i].short_name) {
			shortopts[n_short++] = options[i].short_name;
			if (options[i].has_arg)
				shortopts[n_short++] = ':';
		}
	}
	longopts[N_OPTIONS] = (struct option){ NULL, 0, NULL, 0 };
	shortopts[n_short] = 0;

	while ((opt = getopt_long(argc, argv, shortopts, longopts, NULL)) != -1) {
		const struct opt_def *o = NULL;
		if (opt >= OPT_INDEX_BASE)
			o = &options[opt - OPT_INDEX_BASE];
		for (size_t i = 0; !o && opt != '?' && i < N_OPTIONS; i++)
			if (options[i].short_name == opt)
				o = &options[i];
		if (!o) {
			usage(stderr);
			return EXIT_USAGE;
		}
		int rc = o->apply(cl, o, optarg);
		if (rc != OPT_GO_ON)
			return rc;
	}
	if (optind < argc || !cl->ifname || !cl->n_devs) {
		fprintf(stderr, "cosim: %s\n",
			optind < argc ? "unexpected argument"
			: !cl->ifname ? "--interface is required"
				      : "at least one --device is required");
		usage(stderr);
		return EXIT_USAGE;
	}
	return OPT_GO_ON;
}

/* ---- start-up ------------------------------------------------------------ */

/* Loads every --device and creates its node; returns an exit code. */
static int create_nodes(struct app *app, const struct cmdline *cl, uint64_t now)
{
	char err[COSIM_ERR_MAX];

	for (int i = 0; i < cl->n_devs; i++) {
		cosim_device dev;
		cosim_node_config nc = { 0 };
		char key[128];
		if (cosim_device_load(&dev, cl->devs[i].file, &cl->devs[i].opts, err, sizeof err)) {
			fprintf(stderr, "cosim: %s\n", err);
			return EXIT_DEVICE;
		}
		for (int k = 0; k < app->n_nodes; k++) {
			if (cosim_node_config_id(app->nodes[k]) == dev.node_id &&
			    dev.node_id != 255) {
				fprintf(stderr, "cosim: %s: node-ID %u is used twice\n",
					cl->devs[i].file, dev.node_id);
				cosim_device_free(&dev);
				return EXIT_USAGE;
			}
		}
		if (cl->loopback)
			dev.loopback_enabled = true;
		nv_key(key, sizeof key, cl->devs[i].file, dev.node_id);
		nc.dev = &dev;
		nc.nv_dir = cl->nv_dir;
		nc.nv_key = key;
		nc.faults = cl->faults;
		nc.autostart = cl->autostart;
		nc.sdo_timeout_ms = cl->sdo_timeout_ms;
		nc.quiet = app->quiet;
		nc.out = out_frame;
		nc.out_ctx = app;
		nc.now_us = now;
		if (cosim_node_create(&app->nodes[app->n_nodes], &nc, err, sizeof err)) {
			fprintf(stderr, "cosim: %s\n", err);
			return EXIT_DEVICE;
		}
		app->n_nodes++;
	}
	return EXIT_OK;
}

/* The descriptors of the loop; -1 = not open. */
struct loop_fds {
	int efd, tfd, sfd, cfd;
};

/* Opens the CAN port, epoll, the timer, the signals and the control
 * socket; returns an exit code. */
static int open_loop(struct app *app, const struct cmdline *cl, const sigset_t *mask,
		     struct loop_fds *fds)
{
	/* After the device files: a bad file is reported as such (exit 3)
	 * even where there is no CAN. Nodes send nothing before their first
	 * tick, in the loop below. */
	can_port_config pc = { .ifname = cl->ifname, .bitrate = 125000 };
	const char *what = NULL;
	int prc = can_port_open(&app->port, &pc, &what);
	if (prc) {
		fprintf(stderr, "cosim: %s: %s: %s\n", cl->ifname, what ? what : "open",
			strerror(-prc));
		return EXIT_CAN;
	}

	fds->efd = epoll_create1(EPOLL_CLOEXEC);
	fds->tfd = timerfd_create(CLOCK_MONOTONIC, TFD_CLOEXEC | TFD_NONBLOCK);
	fds->sfd = signalfd(-1, mask, SFD_CLOEXEC | SFD_NONBLOCK);
	if (fds->efd < 0 || fds->tfd < 0 || fds->sfd < 0) {
		fprintf(stderr, "cosim: epoll/timerfd/signalfd: %s\n", strerror(errno));
		return EXIT_RUNTIME;
	}
	if (cl->control) {
		fds->cfd = open_control(cl->control);
		if (fds->cfd < 0) {
			fprintf(stderr, "cosim: --control %s: %s\n", cl->control, strerror(errno));
			return EXIT_USAGE;
		}
	}
	const int watched[] = { can_port_fd(app->port), fds->tfd, fds->sfd, fds->cfd };
	for (size_t i = 0; i < sizeof watched / sizeof watched[0]; i++) {
		struct epoll_event ev = { .events = EPOLLIN, .data.fd = watched[i] };
		if (watched[i] >= 0)
			epoll_ctl(fds->efd, EPOLL_CTL_ADD, watched[i], &ev);
	}
	return EXIT_OK;
}

/* ---- the loop ------------------------------------------------------------ */

static void handle_signals(struct app *app, int sfd)
{
	struct signalfd_siginfo si;

	while (read(sfd, &si, sizeof si) == sizeof si) {
		if (si.ssi_signo == SIGUSR1) {
			for (int i = 0; i < app->n_nodes; i++) {
				cosim_faults *f = cosim_node_faults(app->nodes[i]);
				f->hb_stop = !f->hb_stop;
				cosim_log(app->quiet, "SIGUSR1: node %u heartbeat %s",
					  cosim_node_config_id(app->nodes[i]),
					  f->hb_stop ? "stopped" : "running");
			}
		} else if (si.ssi_signo != SIGHUP) {
			cosim_log(app->quiet, "%s: exiting", strsignal((int)si.ssi_signo));
			app->quit = true;
		}
	}
}

/* Runs until quit; returns an exit code. */
static int run_loop(struct app *app, const struct loop_fds *fds)
{
	bool want_out = false;
	int rc = EXIT_OK;

	while (!app->quit) {
		struct epoll_event evs[8];

		uint64_t now = mono_us();
		run_timers(app, now);
		can_port_flush(app->port, now);
		bool w = can_port_wants_writable(app->port);
		if (w != want_out) {
			struct epoll_event ce = { .events = EPOLLIN | (w ? EPOLLOUT : 0),
						  .data.fd = can_port_fd(app->port) };
			epoll_ctl(fds->efd, EPOLL_CTL_MOD, ce.data.fd, &ce);
			want_out = w;
		}
		arm_timer(app, fds->tfd, now);

		int nev = epoll_wait(fds->efd, evs, 8, -1);
		if (nev < 0) {
			if (errno == EINTR)
				continue;
			fprintf(stderr, "cosim: epoll_wait: %s\n", strerror(errno));
			rc = EXIT_RUNTIME;
			break;
		}
		now = mono_us();
		for (int k = 0; k < nev; k++) {
			int fd = evs[k].data.fd;
			if (fd == fds->tfd) {
				uint64_t exp;
				while (read(fds->tfd, &exp, sizeof exp) > 0)
					;
			} else if (fd == fds->sfd) {
				handle_signals(app, fds->sfd);
			} else if (fd == fds->cfd) {
				handle_control(app, fds->cfd, now);
			} else if (fd == can_port_fd(app->port)) {
				if ((evs[k].events & EPOLLIN) && handle_can(app, now)) {
					rc = EXIT_RUNTIME;
					app->quit = true;
				}
				if (evs[k].events & EPOLLOUT)
					can_port_flush(app->port, now);
			}
		}
	}
	/* Frames still queued (an answer to the last request) go out first. */
	can_port_flush(app->port, mono_us());
	return rc;
}

static void close_all(struct app *app, const struct cmdline *cl, const struct loop_fds *fds)
{
	if (app->local_dropped)
		cosim_log(app->quiet, "%llu local frames dropped (queue full)",
			  (unsigned long long)app->local_dropped);
	for (int i = 0; i < app->n_nodes; i++)
		cosim_node_destroy(app->nodes[i]);
	can_port_close(app->port);
	if (fds->cfd >= 0) {
		close(fds->cfd);
		unlink(cl->control);
	}
	if (fds->sfd >= 0)
		close(fds->sfd);
	if (fds->tfd >= 0)
		close(fds->tfd);
	if (fds->efd >= 0)
		close(fds->efd);
}

int main(int argc, char **argv)
{
	static struct app app; /* large (local queue): not on the stack */
	static struct cmdline cl;
	struct loop_fds fds = { -1, -1, -1, -1 };
	sigset_t mask;
	if (cogw_version_asked("cosim", argc, argv))
		return 0;
	int rc = parse_cmdline(&cl, argc, argv);

	if (rc != OPT_GO_ON)
		return rc;
	app.quiet = cl.quiet;

	/* Signals first: a SIGTERM during start-up is not lost. */
	sigemptyset(&mask);
	sigaddset(&mask, SIGTERM);
	sigaddset(&mask, SIGINT);
	sigaddset(&mask, SIGUSR1);
	sigaddset(&mask, SIGHUP);
	sigprocmask(SIG_BLOCK, &mask, NULL);
	signal(SIGPIPE, SIG_IGN);

	rc = create_nodes(&app, &cl, mono_us());
	if (rc == EXIT_OK)
		rc = open_loop(&app, &cl, &mask, &fds);
	if (rc == EXIT_OK) {
		cosim_log(app.quiet, "%d node(s) on %s%s%s", app.n_nodes, cl.ifname,
			  cl.control ? ", control " : "", cl.control ? cl.control : "");
		rc = run_loop(&app, &fds);
	}
	close_all(&app, &cl, &fds);
	return rc;
}
