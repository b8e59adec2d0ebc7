"""it2ntest -- helpers shared by the Python test scripts under tests/.

Scripts import it without installing anything:

    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
    from it2ntest import ports, report

ports   free loopback ports below the kernel's ephemeral range, unique per run
report  ok/FAIL/skip lines in the runner's conventions and the exit status
proc    run() with a timeout, wait_port() for a listener
daemon  one it2nd process: start, wait until it listens, stop, kill -9, its log
broker  mosquitto on its own configuration: start, wait for its listeners, stop
modbus  Modbus TCP on a raw socket: MBAP frames, FC 03/04 reads, FC 16 writes
"""
