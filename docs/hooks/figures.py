"""The site's figures are the ones ``results/`` keeps beside the runs that drew them. A page links one as
``../results/...`` (README, whose front the home page includes, as ``results/...``), which also resolves when
the page is read in the repository; the site serves it at ``results/...``, copied from there, and the link is
rewritten to point at it."""
from __future__ import annotations

import re
from pathlib import Path

from mkdocs.structure.files import File

FIGURE = re.compile(r"\]\((?:\.\./)?(results/[^)\s]+\.(?:png|svg))\)")


def on_files(files, config):
    root = Path(config.config_file_path).parent
    for page in [*Path(config.docs_dir).glob("*.md"), root / "README.md"]:
        for path in FIGURE.findall(page.read_text(encoding="utf-8")):
            if files.get_file_from_path(path) is None:
                files.append(File(path, src_dir=str(root), dest_dir=config.site_dir,
                                  use_directory_urls=config.use_directory_urls))
    return files


def on_page_markdown(markdown, page, config, files):
    return FIGURE.sub(r"](\1)", markdown)
