# Debian packages the build and tests need. `make deps` checks with dpkg
# first, so it is a fast no-op when everything is present; as root it installs
# what is missing with apt-get, otherwise it names the packages and fails.
DEB_PACKAGES := gcc make pkg-config valgrind libcmocka-dev libmodbus-dev liburing-dev libinih-dev \
  libusb-1.0-0-dev umockdev libumockdev-dev gcc-arm-none-eabi libnewlib-arm-none-eabi \
  qemu-system-arm mbpoll python3 python3-pymodbus python3-serial-asyncio cppcheck clang clang-format libclang-rt-14-dev \
  systemd gnuplot-nox libmicrohttpd-dev prometheus \
  libmosquitto-dev libprotobuf-c-dev protobuf-c-compiler libssl-dev mosquitto python3-paho-mqtt openssl

deps: ## Install missing Debian packages (apt-get as root, else name them)
	@missing=""; for p in $(DEB_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -z "$$missing" ]; then exit 0; fi; \
	if [ "$$(id -u)" = 0 ]; then \
	  echo "deps: installing$$missing"; \
	  export DEBIAN_FRONTEND=noninteractive; \
	  apt-get install -y --no-install-recommends $$missing >/dev/null 2>&1 || \
	  { apt-get update >/dev/null && apt-get install -y --no-install-recommends $$missing; }; \
	else \
	  echo "deps: missing Debian packages:$$missing" >&2; \
	  echo "deps: run as root: apt-get install$$missing" >&2; exit 1; \
	fi
