# Sourced by a device run's script (bench/results/*/device.sh), on a lent many-core machine
# from the repository root: no Ray there (its 79 MB cp312 wheel does not fit the 64 MiB the
# machine is sent), so the runs roll out in-process. Installs the wheels the image lacks,
# carried in .devwheels/ (ignored through .git/info/exclude), and the project, unless
# INSTALL=0 (a try on a machine that has them); puts that Python's scripts on PATH (gaitforge)
# and gives torch one thread per process. The wheels (39 MB) were fetched with
#   pip download --only-binary=:all: --python-version 3.12 --no-deps -d .devwheels \
#     --platform manylinux2014_x86_64 --platform manylinux_2_17_x86_64 \
#     --platform manylinux_2_27_x86_64 --platform manylinux_2_28_x86_64 --platform any \
#     mujoco==3.17.0 pydantic==2.14.4 pydantic_core==2.50.5 pydantic-settings==2.16.3 \
#     python-dotenv==1.2.4 gymnasium==1.4.0 Farama-Notifications==0.0.6 glfw==2.11.0 \
#     foxglove-sdk==0.30.3 mcap==1.6.0 zstandard==0.25.0 cffi==2.1.1 pycparser==3.12 \
#     annotated-types==0.8.0 typing-inspection==0.4.5 typing_extensions==4.16.0
if [ "${INSTALL:-1}" = 1 ]; then
  python3 -m pip install -q --no-index --no-deps .devwheels/*.whl
  python3 -m pip install -q --no-index --no-deps --no-build-isolation .
fi
PATH="$(python3 -c 'import os, sys; print(os.path.dirname(sys.executable))'):$PATH"
nproc
export PATH OMP_NUM_THREADS=1
