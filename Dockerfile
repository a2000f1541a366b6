# The project on Debian 13 "trixie" (dolfinx 0.9.0) from Debian's packages.
# No Docker engine runs on the development machines: `make test-trixie` (a debootstrap root with
# the same package list) is what proves this environment in CI.
FROM debian:trixie
ENV DEBIAN_FRONTEND=noninteractive \
    OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 \
    OMPI_MCA_btl_vader_single_copy_mechanism=none
COPY scripts/debian-packages.txt /tmp/debian-packages.txt
RUN apt-get update \
 && apt-get install -y --no-install-recommends $(grep -v '^#' /tmp/debian-packages.txt) \
 && rm -rf /var/lib/apt/lists/*
WORKDIR /fsi
COPY . /fsi
RUN FSI_VENV=/opt/fsi-venv scripts/setup
ENV PATH=/opt/fsi-venv/bin:$PATH
ENTRYPOINT ["fsi"]
CMD ["--help"]
