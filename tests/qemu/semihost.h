/*
 * ARM semihosting for the emulated Cortex-M3 test image (qemu mps2-an385,
 * -semihosting-config enable=on,target=native). Output and exit status go to
 * the host through `bkpt 0xab`; nothing else of the host is used.
 */
#ifndef IT2N_SEMIHOST_H
#define IT2N_SEMIHOST_H

/* Write a NUL-terminated string to the host console (SYS_WRITE0). */
void it2n_sh_write0(const char *s);

/*
 * End the emulation with exit status `code` (SYS_EXIT_EXTENDED,
 * ADP_Stopped_ApplicationExit + subcode: qemu exits with `code`). Never
 * returns.
 */
void it2n_sh_exit(int code);

#endif /* IT2N_SEMIHOST_H */
