# What scripts/device_check.sh installs on a GPU machine (and scripts/fetch_wheels.sh downloads for one without
# internet): pyproject's base dependencies that training, evaluation and the tests import, and theirs, pinned to the
# versions this tree is tested with. Never torch: the GPU machine's own CUDA build stays.
# torchrl and its torch extensions go in with --no-deps (they would pull a torch).
NODEPS=(torchrl==0.14.1 tensordict==0.14.3 hoptorch==0.1.4 pyvers==0.2.3)
# none of these depends on torch; unpinned ones keep whatever the machine already has
PLAIN=(numpy pyyaml==6.0.3 pydantic==2.13.4 pydantic_core==2.46.4 annotated-types==0.7.0 typing-inspection==0.4.2
       "typing_extensions>=4.12" cloudpickle packaging orjson importlib_metadata zipp gymnasium==1.4.0
       farama-notifications matplotlib contourpy cycler fonttools kiwisolver pillow pyparsing python-dateutil six
       "setuptools>=70.1" tqdm typer annotated-doc click shellingham rich markdown-it-py mdurl pytest iniconfig pluggy pygments)
