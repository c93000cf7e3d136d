"""`dancesynth serve`: a local web page for the main job (FastAPI + a plain HTML/CSS/JS page, all offline).

``server.py`` is the HTTP API and serves ``static/`` (the page); ``jobs.py`` keeps jobs as JSON files under the
data folder and runs them one at a time in a spawned worker process; ``tasks.py`` is what a worker runs (dance,
appearance training, extraction preview, demo); ``job_folder.py`` names the files of a job's folder that both use;
``uploads.py`` receives uploads as they stream, under names the server chooses.
"""
