"""The one installed package, ``dsim``, from the repository's folders.

pyproject.toml holds the metadata; this file only says where each part of ``dsim``
lives, a mapping pyproject.toml cannot discover by itself: the folders keep the
design card's layout and install as parts of ``dsim``.  examples/, tests/ and
benchmarks/ are for people and CI, not installed.
"""
from setuptools import find_namespace_packages, find_packages, setup

#: import name -> folder
FOLDERS = {
    "dsim": "dsim",
    "dsim.master": "master",
    "dsim.fmus": "fmus",
    "dsim.build_fmus": "build_fmus",
    "dsim.serve": "serve",
    "dsim.ssp": "ssp",  # the shipped scenes' sources, for `dsim build-fmus --out DIR`
}
#: folders of files, not code (listed as packages, which is how setuptools ships data)
DATA = {"dsim.serve": ["templates", "static"], "dsim.ssp": ["*"]}

packages, package_data = [], {}
for name, folder in FOLDERS.items():
    packages += [name] + [f"{name}.{sub}" for sub in find_packages(folder)]
    for pattern in DATA.get(name, ()):
        data = find_namespace_packages(folder, include=[pattern, pattern + ".*"],
                                       exclude=["*__pycache__*"])
        for sub in data:
            packages.append(f"{name}.{sub}")
            package_data[f"{name}.{sub}"] = ["*"]

setup(packages=packages, package_dir=FOLDERS, package_data=package_data)
