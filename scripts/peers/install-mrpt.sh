#!/bin/sh
# Installs the MRPT peer of `cargo xtask eval speed` from Debian's archive, by name:
# mrpt-apps (rbpf-slam, carmen2rawlog), libmrpt-obs-dev (the headers our converter
# scripts/peers/rawlog-to-sf.cpp compiles against) and a C++ compiler. Needs root.
set -eu
apt-get update
apt-get install -y mrpt-apps libmrpt-obs-dev g++
