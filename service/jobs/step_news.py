"""News of finished campaign steps, from the Celery workers to the campaign's coordinator.

A worker that finishes a step pushes its id onto a Redis list of the campaign
(``tell_step_done``); the coordinator blocks on that list (``wait_for_news``) and looks at
the database as soon as news comes, so it waits neither for a poll nor with a busy loop.
News is only a wake-up call: the step's result is in the database, and the coordinator
also looks there every ``wait_for_news`` timeout, so news lost with Redis costs a second.
With a broker other than Redis there is no news and the coordinator polls.
"""

from __future__ import annotations

import contextlib

import redis

NEWS_KEPT = 3600  # seconds a coordinator's news list outlives its last news


def is_redis(broker_url: str) -> bool:
    """Whether the broker is Redis (news, and a look at the messages it holds, need it)."""
    return broker_url.startswith(("redis://", "rediss://", "unix://"))


def step_news_key(job: str, position: int) -> str:
    """The Redis list a campaign's coordinator waits on: its workers push a step's id
    there when they finish it (``tell_step_done``)."""
    return f"scengen-steps-done.{job}.{position}"


def tell_step_done(broker_url: str, job: str, position: int, step: str) -> None:
    """Wake the coordinator waiting for ``step`` (best effort: it also looks at the
    database every second, so news lost with Redis only costs that second)."""
    if not is_redis(broker_url):
        return
    client = redis.Redis.from_url(broker_url)
    try:
        key = step_news_key(job, position)
        with client.pipeline(transaction=False) as pipe:
            pipe.rpush(key, step)
            pipe.expire(key, NEWS_KEPT)
            pipe.execute()
    except redis.RedisError:
        pass
    finally:
        client.close()


def wait_for_news(client: redis.Redis, job: str, position: int, timeout: float) -> None:
    """Block until a step of the campaign is done, or ``timeout`` seconds; take all the
    news there is (one look at the database answers it all)."""
    key = step_news_key(job, position)
    if client.blpop([key], timeout=timeout) is not None:
        with contextlib.suppress(redis.RedisError):
            client.delete(key)
