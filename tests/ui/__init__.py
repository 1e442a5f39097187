"""The MLflow UI acceptance check: headless Chromium, driven by Playwright, on a real ``mlflow ui``.

``make ui-check`` runs :mod:`tests.ui.check` after ``make run``. :mod:`tests.ui.expect` reads what
the store holds and decides what each page must show, :mod:`tests.ui.pages` builds the pages'
addresses and checks, :mod:`tests.ui.dom` reads a rendered page, :mod:`tests.ui.browser` renders
it; :mod:`tests.ui.store` builds a small store in the pipeline's tracking layout for the tests.
"""
