// exit_hook.c - find who ends a process with exit(n) / _exit(n) and no message.
//
// An LD_PRELOAD library: every exit(), _exit() or _Exit() with a non-zero status writes a file
// to $EXITSHIM_DIR (default /tmp/exitlog) with the command line, the C stack and, when the
// process is a Python interpreter, the Python stack of the current thread; then exits as asked.
// It found the CI's "silent deaths" (gmsh 4.8's Msg::Error calling exit(1) on an API call made
// before gmsh.initialize(); see millimpact.geometry.builders.gmsh_session).
//
//   gcc -O1 -shared -fPIC -o /tmp/exit_hook.so tools/exit_hook.c -ldl
//   mkdir -p /tmp/exitlog
//   LD_PRELOAD=/tmp/exit_hook.so EXITSHIM_DIR=/tmp/exitlog .ci/run     # or any command
//   grep -l "" /tmp/exitlog/*     # one file per non-zero exit: expected ones (exit 2 of bad input) too
//
// Not part of the package; a debugging aid for developers.
#define _GNU_SOURCE
#include <dlfcn.h>
#include <execinfo.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <time.h>

static void logit(const char *who, int status) {
    if (status == 0) return;
    const char *dir = getenv("EXITSHIM_DIR");
    if (!dir) dir = "/tmp/exitlog";
    char path[512];
    struct timespec ts; clock_gettime(CLOCK_REALTIME, &ts);
    snprintf(path, sizeof path, "%s/%ld.%d.%s.%d", dir, (long)ts.tv_sec, (int)getpid(), who, status);
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0) return;
    char buf[8192];
    int cfd = open("/proc/self/cmdline", O_RDONLY);
    if (cfd >= 0) {
        ssize_t n = read(cfd, buf, sizeof buf - 1);
        close(cfd);
        if (n > 0) { for (ssize_t i = 0; i < n; i++) if (!buf[i]) buf[i] = ' '; write(fd, "cmdline: ", 9); write(fd, buf, n); write(fd, "\n", 1); }
    }
    int m = snprintf(buf, sizeof buf, "%s(%d) pid %d ppid %d\n", who, status, (int)getpid(), (int)getppid());
    write(fd, buf, m);
    void *frames[64];
    int k = backtrace(frames, 64);
    backtrace_symbols_fd(frames, k, fd);
    int (*isinit)(void) = (int (*)(void))dlsym(RTLD_DEFAULT, "Py_IsInitialized");
    void *(*gil)(void) = (void *(*)(void))dlsym(RTLD_DEFAULT, "PyGILState_GetThisThreadState");
    const char *(*dump)(int, void *, void *) = (const char *(*)(int, void *, void *))dlsym(RTLD_DEFAULT, "_Py_DumpTracebackThreads");
    if (isinit && dump && gil && isinit()) {
        write(fd, "python:\n", 8);
        dump(fd, NULL, gil());
    }
    close(fd);
}

// exit(), _exit() and _Exit(): log, then call the real one
#define HOOK(name)                                                    \
    void name(int status) {                                           \
        logit(#name, status);                                         \
        void (*real)(int) = (void (*)(int))dlsym(RTLD_NEXT, #name);   \
        real(status);                                                 \
        __builtin_unreachable();                                      \
    }
HOOK(exit)
HOOK(_exit)
HOOK(_Exit)
