# Sourced by the Python interop checks: creates (once) the pinned virtual environment
# .cache/py-venv and sets PY to its interpreter. Needs python3 with the venv module
# (Debian: apt-get install python3-venv) and PyPI access the first time.
PY_VENV=.cache/py-venv
PY_REQUIREMENTS="tflite-micro==0.dev20261023182759 numpy==2.4.6 pillow==13.0.0"
PY=$PY_VENV/bin/python
if [ ! -x "$PY" ] || [ "$(cat "$PY_VENV/.orbfix-requirements" 2>/dev/null)" != "$PY_REQUIREMENTS" ]; then
  command -v python3 >/dev/null 2>&1 ||
    { echo "orbfix: python3 is needed for the interop checks (apt-get install python3 python3-venv)" >&2; exit 1; }
  rm -rf "$PY_VENV"
  python3 -m venv "$PY_VENV" ||
    { echo "orbfix: cannot create $PY_VENV (apt-get install python3-venv)" >&2; exit 1; }
  # shellcheck disable=SC2086
  "$PY_VENV/bin/pip" install -q --disable-pip-version-check $PY_REQUIREMENTS
  echo "$PY_REQUIREMENTS" >"$PY_VENV/.orbfix-requirements"
fi
